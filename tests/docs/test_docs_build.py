"""The documentation site builds from the checkout with warnings as errors, and every ``crowd_env``
name it or the README cites exists."""
from __future__ import annotations

import importlib
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"

pytest.importorskip("sphinx")
pytest.importorskip("myst_parser")
pytest.importorskip("furo")


def test_docs_build_with_warnings_as_errors(tmp_path):
    out = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", str(DOCS),
                          str(tmp_path / "html")], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stdout + out.stderr
    assert (tmp_path / "html" / "index.html").exists()
    assert (tmp_path / "html" / "architecture" / "index.html").exists()


NAME = re.compile(r"`(?:\{py:\w+\}`)?(crowd_env(?:\.[A-Za-z_][A-Za-z0-9_]*)+)`")


def _resolve(dotted: str):
    parts = dotted.split(".")
    for k in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:k]))
        except ModuleNotFoundError:
            continue
        for attr in parts[k:]:
            obj = getattr(obj, attr)
        return obj
    raise ModuleNotFoundError(dotted)


def test_every_cited_crowd_env_name_exists():
    pages = sorted(DOCS.rglob("*.md")) + [ROOT / "README.md"]
    names = {(p.relative_to(ROOT), m) for p in pages for m in NAME.findall(p.read_text())}
    assert len(names) > 20  # the pages cite the code they describe
    missing = []
    for page, name in sorted(names):
        try:
            _resolve(name)
        except (ImportError, AttributeError) as exc:
            missing.append(f"{page}: {name} ({exc})")
    assert not missing, "\n".join(missing)


def test_every_cited_test_file_and_script_exists():
    pages = sorted(DOCS.rglob("*.md")) + [ROOT / "README.md"]
    cited = {(p.relative_to(ROOT), m) for p in pages
             for m in re.findall(r"`((?:tests|scripts|benchmarks)/[\w/]+\.py)", p.read_text())}
    assert cited
    missing = [f"{page}: {path}" for page, path in sorted(cited) if not (ROOT / path).exists()]
    assert not missing, "\n".join(missing)
