"""Printing terms and types in Celf's concrete syntax: :func:`show`. It lives with the terms
(``terms.py``), whose ``repr`` is their printed form; this module is where the rest of the engine
and the library take it from. A program's own printing (implicit arguments hidden) is
``Program.show``."""

from .terms import show

__all__ = ["show"]
