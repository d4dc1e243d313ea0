"""A fuzzing harness for the command line: grammar-aware mutations of every input kind.

:mod:`.mutate` turns the bundled inputs (CLF models, ROAR specs, job, property, scenario
and TCA model TOML, traces) into malformed ones with hypothesis strategies; :mod:`.runner`
runs ``roar-verify`` on each case in-process, in a forked child with a time bound, and
classifies the outcome. ``tests/test_fuzz.py`` runs a bounded number of cases;
``python bench/fuzz.py --cases N`` runs many and prints the tallies (docs/checking.md).
"""

from .mutate import Case, cases
from .runner import Outcome, run_case

__all__ = ["Case", "cases", "Outcome", "run_case"]
