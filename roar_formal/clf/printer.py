"""Printing terms and types in Celf's concrete syntax: :func:`show` and the table of implicit
arguments it hides (``IMPLICIT``). They live with the terms (``terms.py``), whose ``repr`` is
their printed form; this module is where the rest of the engine and the library take them from.
"""

from .terms import IMPLICIT, show

__all__ = ["IMPLICIT", "show"]
