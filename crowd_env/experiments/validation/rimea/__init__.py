"""The RiMEA verification suite (RiMEA 4.1.1, Annex 1: the flat tests 1, 4, 5, 6, 7, 9, 10, 11, 12a-d, 15,
16), run on crowd_env and, with the benchmark extra, on JuPedSim beside it. Command: ``crowd-rimea``.

One module per test (``t<nn>_<name>.py``, each a :class:`~.base.RimeaTest` registered by number); the
scenarios are data in :mod:`crowd_env.scenarios.rimea`; :mod:`.suite` runs and reports them.
"""
import importlib
import pkgutil

from .base import BackendRun, RimeaTest, Verdict, register_test, rimea_tests, select_tests
from .suite import TestResult, format_table, run_suite

for _module in sorted(m.name for m in pkgutil.iter_modules(__path__) if m.name.startswith("t")):
    importlib.import_module(f"{__name__}.{_module}")  # each registers its test(s)

__all__ = ["BackendRun", "RimeaTest", "Verdict", "TestResult", "register_test", "rimea_tests", "select_tests",
           "run_suite", "format_table"]
