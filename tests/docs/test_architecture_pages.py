"""The architecture pages match the tree: the package tree of docs/architecture/layers.md (as the site shows it, its
scenario modules' lines generated: docs/_ext/generated_lists.py) lists every module and package of crowd_env and
baselines and nothing else, and every module the architecture pages name exists."""
from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PAGES = sorted((ROOT / "docs" / "architecture").glob("*.md"))
sys.path.insert(0, str(ROOT / "docs" / "_ext"))
from generated_lists import expand  # noqa: E402  the pages as the site shows them (the scenario modules' lines)
ENTRY = re.compile(r"^( *)([\w.]+/|[\w.]+\.py)(?:\s|$)")


def tree_entries(text: str) -> set:
    """The paths of the first code block after '## The package tree', from its indentation (two spaces a level)."""
    block = text.split("## The package tree", 1)[1].split("```", 2)[1]
    stack, paths = [], set()
    for line in block.splitlines():
        m = ENTRY.match(line)
        if not m:
            continue
        depth, name = len(m.group(1)) // 2, m.group(2)
        assert len(m.group(1)) % 2 == 0 and depth <= len(stack), f"bad indentation in the tree: {line!r}"
        stack = stack[:depth]
        path = "/".join(stack + [name.rstrip("/")])
        if name.endswith("/"):
            stack.append(name.rstrip("/"))
            if path in ("crowd_env", "baselines") or depth:
                paths.add(path + "/")
        elif depth:
            paths.add(path)
    return paths


def package_entries() -> set:
    paths = set()
    for top in ("crowd_env", "baselines"):
        for p in (ROOT / top).rglob("*.py"):
            rel = p.relative_to(ROOT)
            if "__pycache__" in rel.parts:
                continue
            if p.name == "__init__.py":
                paths.add(rel.parent.as_posix() + "/")
            else:
                paths.add(rel.as_posix())
    return paths


def test_the_tree_lists_every_module_and_nothing_else():
    listed = tree_entries(expand((ROOT / "docs" / "architecture" / "layers.md").read_text()))
    actual = package_entries()
    assert not actual - listed, f"modules missing from the tree of layers.md: {sorted(actual - listed)}"
    assert not listed - actual, f"the tree of layers.md names modules that do not exist: {sorted(listed - actual)}"


def test_the_tree_reader_sees_a_missing_and_an_invented_module():
    text = expand((ROOT / "docs" / "architecture" / "layers.md").read_text())
    listed = tree_entries(text)
    assert "crowd_env/core/step.py" in listed and "crowd_env/experiments/running/store.py" in listed
    dropped = tree_entries(re.sub(r"^ *store\.py .*\n", "", text, count=1, flags=re.M))
    assert "crowd_env/experiments/running/store.py" not in dropped
    invented = tree_entries(text.replace("    step.py ", "    step.py  x\n    stepper.py ", 1))
    assert "crowd_env/core/stepper.py" in invented


def test_every_module_the_architecture_pages_name_exists():
    missing = []
    for page in PAGES:
        text = page.read_text()
        for name in set(re.findall(r"\b(crowd_env(?:\.\w+)+|baselines(?:\.\w+)+)", text)):
            parts = name.split(".")
            # the longest prefix that is a module or package; what follows may be an attribute
            for k in range(len(parts), 0, -1):
                base = ROOT.joinpath(*parts[:k])
                if base.with_suffix(".py").exists() or (base / "__init__.py").exists():
                    break
            else:
                missing.append((page.name, name))
                continue
            if k < len(parts) - 1 and parts[k][0].islower() and not (base.with_suffix(".py").exists()):
                missing.append((page.name, name))  # a.b.c.d where a.b is a package but c is no module of it
        for path in set(re.findall(r"\b((?:crowd_env|baselines)/[\w/]+\.py)\b", text)):
            if not (ROOT / path).exists():
                missing.append((page.name, path))
    assert not missing, f"the architecture pages name modules that do not exist: {sorted(missing)}"
