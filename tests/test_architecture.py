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
