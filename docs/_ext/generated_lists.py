"""The lists of the documentation that follow the scenarios, generated from the package when the pages are read.

A new scenario is a module of ``crowd_env/scenarios/`` (its factory registered with ``@register_scenario``) and its
test: nothing in the pages is edited for it. Three lists come from the package instead of being kept by hand, each
where a marker line stands in the page:

- ``docs/scenarios.md``: ``<!-- generated: scenario table -->``, the table of the scenarios the modules of
  ``crowd_env/scenarios/`` register (name and aliases, the module's summary, the Gymnasium ids that run it);
- ``docs/api.md``: ``.. generated: automodules of crowd_env.scenarios`` (an RST comment inside an ``eval-rst``
  block), one ``automodule`` per module and package of ``crowd_env/scenarios/``;
- ``docs/architecture/layers.md``: ``    (generated: one line per scenario module)`` in the package tree, a line per
  module of ``crowd_env/scenarios/`` that registers a scenario, with the first line of its docstring.

:func:`expand` does it on a page's text (the tests read the pages through it: ``tests/docs/``); :func:`setup`
makes it a Sphinx extension (``docs/conf.py``) that expands every page as Sphinx reads it.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = ROOT / "crowd_env" / "scenarios"
TABLE_MARKER = "<!-- generated: scenario table -->"
API_MARKER = ".. generated: automodules of crowd_env.scenarios"
TREE_MARKER = "    (generated: one line per scenario module)"
REGISTERS = re.compile(r"^@?register_scenario\(", re.M)  # a module-level registration


def _summary(path: Path) -> str:
    """The first line of a module's docstring, without its final full stop."""
    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
    return doc.strip().split("\n", 1)[0].rstrip(".")


def scenario_modules(folder: Path = SCENARIOS) -> list:
    """The modules of ``folder`` (not its subpackages) that register a scenario, by file name."""
    return sorted(p for p in folder.glob("*.py") if p.name != "__init__.py" and REGISTERS.search(p.read_text()))


def tree_lines(folder: Path = SCENARIOS) -> str:
    """The package tree's lines of the scenario modules (indented as children of ``scenarios/``)."""
    return "\n".join(f"    {p.name:<32}{_summary(p)[:1].lower()}{_summary(p)[1:]}" for p in scenario_modules(folder))


def automodules(folder: Path = SCENARIOS, package: str = "crowd_env.scenarios") -> str:
    """``automodule`` directives of the package ``folder`` and of its modules and subpackages, recursively."""
    lines = [f".. automodule:: {package}", "   :no-members:"]
    for p in sorted(folder.iterdir()):
        if p.suffix == ".py" and p.name != "__init__.py":
            lines.append(f".. automodule:: {package}.{p.stem}")
        elif p.is_dir() and (p / "__init__.py").exists():
            lines.append(automodules(p, f"{package}.{p.name}"))
    return "\n".join(lines)


def scenario_table(folder: Path = SCENARIOS, package: str = "crowd_env.scenarios") -> str:
    """The Markdown table of the scenarios the modules of ``folder`` (the package ``package``) register, from the
    registry."""
    from crowd_env.registration import ENV_IDS
    from crowd_env.scenarios import list_scenarios
    from crowd_env.scenarios.registry import scenario_aliases, scenario_factory

    aliases = {a for name in list_scenarios() for a in scenario_aliases(name)}
    rows = ["| name (aliases) | what | Gymnasium ids |", "|---|---|---|"]
    for module in scenario_modules(folder):
        for name in list_scenarios():
            if name in aliases or scenario_factory(name).__module__ != f"{package}.{module.stem}":
                continue
            known = (name, *scenario_aliases(name))
            also = f" ({', '.join(f'`{a}`' for a in known[1:])})" if known[1:] else ""
            ids = ", ".join(f"`{k.split('/', 1)[1]}`" for k, v in ENV_IDS.items() if v["scenario"] in known) or "—"
            rows.append(f"| `{name}`{also} | {_summary(module)} | {ids} |")
    return "\n".join(rows)


def expand(text: str) -> str:
    """``text`` with each marker line replaced by its list."""
    for marker, make in ((TABLE_MARKER, scenario_table), (API_MARKER, automodules), (TREE_MARKER, tree_lines)):
        if marker in text:
            text = text.replace(marker, make())
    return text


def _expand_page(app, docname, source) -> None:
    source[0] = expand(source[0])


def setup(app) -> dict:
    app.connect("source-read", _expand_page)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
