"""The worked example of docs/architecture/layers.md, "A new walking-model parameter" (issue 51): a cap on the calibrated
agent's intent speed touches its group and the one kernel that reads it, and works.

The page's diff is applied to a copy of the package (each hunk found by its context lines, wherever they now are),
the changed definitions are compared (only ``Intent`` and ``baseline_intents`` of ``crowd_env/walking/agent.py``
differ), and in a fresh process on the copy the page's example runs (the parameter by its name, the Python agent's
intents capped, the compiled agent's equal to them) and, at the parameter's default, the agent's intents are those
of the package as it is, to the bit."""
from __future__ import annotations

import ast
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "architecture" / "layers.md"
TIMEOUT_S = 900  # a cold compilation of the walking model's kernels in the copy, on a busy machine
SECTION = "**A new walking-model parameter**"

DEFAULT_RUN = '''
import sys
import numpy as np
from crowd_env.scenarios import make_scenario
from crowd_env.walking import get_preset
from crowd_env.walking.agent import SocialForceAgent

scenario = make_scenario("seyfried_bottleneck", n_pedestrians=20, seed=0)
sim = scenario.make_simulator(params=get_preset("calibrated").params())
agent = SocialForceAgent(scenario.navigation())
rows = []
for _ in range(30):
    intents, heading = agent(sim)
    rows += [intents.ravel(), heading]
    sim.step(intents, desired_heading_rad=heading)
np.save(sys.argv[1], np.concatenate(rows))
'''


def _section_blocks() -> tuple:
    """``(diff, python code)`` of the example: the first ```diff and ```python blocks of the section."""
    text = PAGE.read_text()
    start = text.index(SECTION)
    end = text.index("\n- **", start + len(SECTION))
    section = text[start:end]
    blocks = re.findall(r"^( *)```(\w+)\n(.*?)^\1```", section, flags=re.M | re.S)
    by_lang = {}
    for indent, lang, body in blocks:
        by_lang.setdefault(lang, "\n".join(line[len(indent):] for line in body.splitlines()) + "\n")
    return by_lang["diff"], by_lang["python"]


def _hunks(diff: str) -> tuple:
    """The file the diff changes and its hunks as ``(old lines, new lines)``."""
    files = re.findall(r"^\+\+\+ b/(\S+)$", diff, flags=re.M)
    hunks, current = [], None
    for line in diff.splitlines():
        if line.startswith(("---", "+++")):
            continue
        if line.startswith("@@"):
            current = ([], [])
            hunks.append(current)
            continue
        tag, body = line[:1], line[1:]
        if tag in (" ", "") and current is not None:
            current[0].append(body)
            current[1].append(body)
        elif tag == "-":
            current[0].append(body)
        elif tag == "+":
            current[1].append(body)
    return files, hunks


def apply_hunks(text: str, hunks) -> str:
    """``text`` with each hunk's old lines (found exactly once) replaced by its new ones."""
    for old, new in hunks:
        old_text, new_text = "\n".join(old) + "\n", "\n".join(new) + "\n"
        assert text.count(old_text) == 1, f"the example's hunk no longer matches the code once:\n{old_text}"
        text = text.replace(old_text, new_text)
    return text


def _definitions(source: str) -> dict:
    """Top-level definitions of a module (name -> its source), and the rest of its statements under ''."""
    tree = ast.parse(source)
    out = {"": []}
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            out[node.name] = ast.unparse(node)
        else:
            out[""].append(ast.unparse(node))
    return out


def test_the_example_touches_its_group_and_its_kernel_only():
    diff, _ = _section_blocks()
    files, hunks = _hunks(diff)
    assert files == ["crowd_env/walking/agent.py"] and len(hunks) == 2
    before = (ROOT / files[0]).read_text()
    after = apply_hunks(before, hunks)
    old, new = _definitions(before), _definitions(after)
    changed = {name for name in set(old) | set(new) if old.get(name) != new.get(name)}
    assert changed == {"Intent", "baseline_intents"}
    # a bad hunk is refused, not applied somewhere else
    with pytest.raises(AssertionError, match="no longer matches"):
        apply_hunks(before, [(["def no_such_kernel():"], ["def no_such_kernel(): pass"])])


def _copy_package(tmp_path: Path) -> Path:
    """The package under ``tmp_path``, with the numba caches of the core (which cannot depend on the walking model)
    and none of the walking model's or any layer above it (their caches could hold the old kernel)."""
    dest = tmp_path / "crowd_env"

    def ignore(folder, names):
        rel = Path(folder).relative_to(ROOT / "crowd_env")
        keep_cache = rel.parts[:1] == ("core",)
        return [n for n in names if n == "__pycache__" and not keep_cache]

    shutil.copytree(ROOT / "crowd_env", dest, ignore=ignore)
    return tmp_path


def _run(code: str, path: Path, cwd: Path, *args):
    script = cwd / "script.py"
    script.write_text(code)
    env = {**os.environ, "PYTHONPATH": str(path), "MPLBACKEND": "Agg"}
    return subprocess.run([sys.executable, str(script), *map(str, args)], cwd=cwd, capture_output=True, text=True,
                          timeout=TIMEOUT_S, env=env)


def test_the_example_runs_on_the_patched_package_and_its_default_changes_nothing(tmp_path):
    diff, example = _section_blocks()
    files, hunks = _hunks(diff)
    root = _copy_package(tmp_path / "pkg")
    target = root / files[0]
    target.write_text(apply_hunks(target.read_text(), hunks))
    work = tmp_path / "work"
    work.mkdir()
    out = _run(example, root, work)
    assert out.returncode == 0, f"the example failed on the patched package:\n{out.stdout[-3000:]}\n{out.stderr[-5000:]}"
    patched = _run(DEFAULT_RUN, root, work, work / "patched.npy")
    assert patched.returncode == 0, patched.stderr[-5000:]
    here = _run(DEFAULT_RUN, ROOT, work, work / "here.npy")
    assert here.returncode == 0, here.stderr[-5000:]
    a, b = np.load(work / "patched.npy"), np.load(work / "here.npy")
    assert a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))
