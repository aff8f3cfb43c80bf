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
    # -j 2: the same site, its pages read and written on both cores of a CI machine (81 -> 63 s on 2 cores)
    out = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-j", "2", "-b", "html",
                          str(DOCS), str(tmp_path / "html")], capture_output=True, text=True, cwd=ROOT)
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


SOURCES = ("crowd_env", "baselines", "scripts", "benchmarks", "docs")


def _source_files():
    for top in SOURCES:
        yield from (p for p in (ROOT / top).rglob("*") if p.suffix in (".py", ".md", ".rst") and "_build" not in p.parts)
    yield ROOT / "README.md"


def test_no_reference_to_files_outside_the_repository():
    outside = re.compile(r"(?:\.\./shared|\bshared/(?:data|docs|papers)\b|design notes?\b)")
    hits = [f"{p.relative_to(ROOT)}:{i}: {line.strip()}" for p in _source_files()
            for i, line in enumerate(p.read_text().splitlines(), 1) if outside.search(line)]
    assert not hits, "\n".join(hits)


def test_every_docs_page_cited_from_the_code_exists():
    cited = {(p.relative_to(ROOT), m) for p in _source_files() if p.suffix == ".py"
             for m in re.findall(r"\bdocs/[\w/.-]+\.md", p.read_text())}
    assert cited  # docstrings send readers to the docs pages
    missing = [f"{src}: {path}" for src, path in sorted(cited) if not (ROOT / path).exists()]
    assert not missing, "\n".join(missing)


def test_every_console_script_is_documented_and_has_an_entry_point():
    import tomllib

    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    table = (DOCS / "getting_started.md").read_text()
    undocumented = [name for name in scripts if f"| `{name}` |" not in table]
    assert not undocumented, f"getting_started.md lists no {undocumented}"
    for name, target in scripts.items():
        module = target.split(":")[0]
        shim = ROOT / "scripts" / f"{module.rsplit('.', 1)[1]}.py"
        assert shim.exists(), f"{name}: no scripts/{shim.name}"
        assert f"from {module} import main" in shim.read_text(), shim


def test_api_reference_covers_every_module():
    modules = set()
    for path in (ROOT / "crowd_env").rglob("*.py"):
        parts = path.relative_to(ROOT).with_suffix("").parts
        modules.add(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    sys.path.insert(0, str(DOCS / "_ext"))
    from generated_lists import expand  # the page as the site reads it (the scenarios' modules generated)

    listed = set(re.findall(r"^\.\. automodule:: ([\w.]+)", expand((DOCS / "api.md").read_text()), flags=re.M))
    assert not modules - listed, f"api.md leaves out {sorted(modules - listed)}"
    assert not listed - modules, f"api.md names modules that do not exist: {sorted(listed - modules)}"
