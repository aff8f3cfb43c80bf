"""One error hierarchy: every exception crowd_env defines lives in crowd_env.errors, derives from
CrowdEnvError and from a builtin, and every ``raise`` in the package raises one of them."""
from __future__ import annotations

import ast
import inspect
from pathlib import Path

import pytest

import crowd_env.errors as errors
from crowd_env.errors import CrowdEnvError

PACKAGE = Path(errors.__file__).parent
BUILTINS = (ValueError, RuntimeError, KeyError, TypeError, OSError, ImportError)
ALLOWED = {"SystemExit", "KeyboardInterrupt", "NotImplementedError", "StopIteration",
           "AttributeError",  # AttributeError: the module __getattr__ protocol
           "_error_class"}  # crowd_env.core.checks: the caller's class, checked to be of the hierarchy


def _classes():
    return [c for _, c in inspect.getmembers(errors, inspect.isclass) if c.__module__ == errors.__name__]


def test_every_error_is_a_crowd_env_error_and_a_builtin():
    classes = _classes()
    assert len(classes) > 20
    for cls in classes:
        assert issubclass(cls, CrowdEnvError), cls
        assert cls is CrowdEnvError or issubclass(cls, BUILTINS), cls


def test_no_module_defines_its_own_exception_class():
    offenders = []
    for path in PACKAGE.rglob("*.py"):
        if path.name == "errors.py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ClassDef):
                bases = {ast.unparse(b).split(".")[-1] for b in node.bases}
                if bases & ({"Exception", "ValueError", "RuntimeError", "KeyError", "TypeError"}
                            | {c.__name__ for c in _classes()}):
                    offenders.append(f"{path.relative_to(PACKAGE)}: class {node.name}")
    assert not offenders, offenders


def test_every_raise_names_an_error_of_the_hierarchy():
    names = {c.__name__ for c in _classes()} | ALLOWED
    offenders = []
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Raise) and isinstance(node.exc, ast.Call):
                func = node.exc.func.func if isinstance(node.exc.func, ast.Call) else node.exc.func  # raise f(x)(...)
                name = ast.unparse(func).split(".")[-1]
                if name not in names:
                    offenders.append(f"{path.relative_to(PACKAGE)}:{node.lineno} raise {name}")
    assert not offenders, offenders


@pytest.mark.parametrize("call, cls, builtin", [
    (lambda: __import__("crowd_env.walking.model", fromlist=["x"]).ModelParams(dt_s=-1.0), errors.ParameterError, ValueError),
    (lambda: __import__("crowd_env.scenarios", fromlist=["x"]).make_scenario("no_such_scenario"), errors.ScenarioError,
     ValueError),
])
def test_raised_errors_are_caught_by_both_bases(call, cls, builtin):
    with pytest.raises(cls) as info:
        call()
    assert isinstance(info.value, CrowdEnvError) and isinstance(info.value, builtin)
