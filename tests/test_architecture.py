"""The layering of docs/architecture/layers.md holds: import-linter's contracts (pyproject.toml,
``[tool.importlinter]``) pass on the package, and fail on a copy with one upward import."""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
pytest.importorskip("importlinter")
LINT = [sys.executable, "-c", "import sys; from importlinter.cli import lint_imports_command; sys.exit(lint_imports_command())"]


def _lint(cwd: Path) -> subprocess.CompletedProcess:
    env = {"PYTHONPATH": str(cwd), "PATH": "/usr/bin:/bin"}
    return subprocess.run(LINT + ["--no-cache"], cwd=cwd, capture_output=True, text=True, env=env)


def test_import_contracts_are_kept():
    out = _lint(ROOT)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "0 broken" in out.stdout and "Layers" in out.stdout


@pytest.mark.parametrize("module, line, contract", [
    ("core/params.py", "    from crowd_env.experiments import runner  # noqa\n", "Layers"),  # lazy import counts
    ("analysis/flow.py", "import crowd_env.envs.crowd_v0  # noqa\n", "Layers"),
    ("envs/rewards/__init__.py", "import baselines  # noqa\n", "never imports baselines"),
    ("walking/agent.py", "import gymnasium  # noqa\n", "knows nothing of RL"),
    ("experiments/running/store.py", "    from crowd_env.experiments.training import ppo  # noqa\n", "Experiments:"),
    ("experiments/output/tables.py", "import crowd_env.experiments.validation.soak  # noqa\n", "Experiments:"),
    ("experiments/training/ppo.py", "import crowd_env.experiments.validation.bottleneck  # noqa\n", "Experiments:"),
    ("files.py", "import crowd_env.core.params  # noqa\n", "atomic file writes"),
])
def test_an_upward_import_breaks_a_contract(tmp_path, module, line, contract):
    shutil.copytree(ROOT / "crowd_env", tmp_path / "crowd_env", ignore=shutil.ignore_patterns("__pycache__", "*.nb?"))
    shutil.copytree(ROOT / "baselines", tmp_path / "baselines", ignore=shutil.ignore_patterns("__pycache__", "*.nb?"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    path = tmp_path / "crowd_env" / module
    text = path.read_text()
    if line.startswith("    "):  # a lazy import inside a function
        text += "\n\ndef _probe():\n" + line
    else:
        text += "\n" + line
    path.write_text(text)
    out = _lint(tmp_path)
    assert out.returncode != 0, out.stdout
    broken = [ln for ln in out.stdout.splitlines() if ln.endswith("BROKEN")]
    assert any(contract in ln for ln in broken), out.stdout


def _import_cycles(root: Path) -> list:
    """The import cycles (strongly connected components of more than one module, lazy imports included) of
    crowd_env and baselines as found under ``root``, each a sorted list of module names."""
    script = r"""
import json, sys
import grimp
sys.setrecursionlimit(100000)
g = grimp.build_graph("crowd_env", "baselines", include_external_packages=False)
edges = {m: sorted(g.find_modules_directly_imported_by(m)) for m in sorted(g.modules)}
index, low, stack, on, cycles = {}, {}, [], set(), []
def visit(v):
    index[v] = low[v] = len(index); stack.append(v); on.add(v)
    for w in edges[v]:
        if w not in index:
            visit(w); low[v] = min(low[v], low[w])
        elif w in on:
            low[v] = min(low[v], index[w])
    if low[v] == index[v]:
        comp = []
        while True:
            w = stack.pop(); on.discard(w); comp.append(w)
            if w == v:
                break
        if len(comp) > 1:
            cycles.append(sorted(comp))
for v in edges:
    if v not in index:
        visit(v)
print(json.dumps(cycles))
"""
    out = subprocess.run([sys.executable, "-c", script], cwd=root, capture_output=True, text=True,
                         env={"PYTHONPATH": str(root), "PATH": "/usr/bin:/bin"})
    assert out.returncode == 0, out.stderr
    import json
    return json.loads(out.stdout)


def test_no_import_cycle_anywhere_in_the_repository():
    pytest.importorskip("grimp")
    assert _import_cycles(ROOT) == []


def test_a_planted_lazy_import_cycle_is_found(tmp_path):
    pytest.importorskip("grimp")
    shutil.copytree(ROOT / "crowd_env", tmp_path / "crowd_env", ignore=shutil.ignore_patterns("__pycache__", "*.nb?"))
    shutil.copytree(ROOT / "baselines", tmp_path / "baselines", ignore=shutil.ignore_patterns("__pycache__", "*.nb?"))
    path = tmp_path / "baselines" / "policy.py"  # baselines.trained imports it; make it import trained back
    path.write_text(path.read_text() + "\n\ndef _probe():\n    from . import trained  # noqa\n")
    cycles = _import_cycles(tmp_path)
    assert ["baselines.policy", "baselines.trained"] in cycles


def _long_functions(roots, limit: int = 80) -> list:
    """(lines, path, name) of every function longer than ``limit`` lines that numba does not compile."""
    import ast

    out = []
    for root in roots:
        for path in sorted(Path(root).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    compiled = any("jit" in ast.unparse(d) for d in node.decorator_list)
                    length = node.end_lineno - node.lineno + 1
                    if length > limit and not compiled:
                        out.append((length, str(path), node.name))
    return out


def test_no_python_function_is_over_80_lines():
    roots = [ROOT / d for d in ("crowd_env", "baselines", "scripts", "benchmarks")]
    assert _long_functions(roots) == []


def test_the_length_rule_sees_a_long_function(tmp_path):
    body = "\n".join(f"    x{i} = {i}" for i in range(81))
    (tmp_path / "m.py").write_text(f"def long():\n{body}\n\n\n@nb.njit\ndef kernel():\n{body}\n")
    found = _long_functions([tmp_path])
    assert [name for _, _, name in found] == ["long"]
