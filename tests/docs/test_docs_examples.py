"""Every ```python block of the documentation pages (``docs/**/*.md`` and ``README.md``) runs, each as a
script of its own in a fresh process (a temporary working folder, so relative paths such as ``runs/`` stay
there), and must exit with 0 within :data:`TIMEOUT_S`. A block that cannot run here on purpose (it needs a
trained model, a cluster, ...) is preceded by the marker ``<!-- not-run: REASON -->`` on the line before
its opening fence, and the reason must be given. Budgets in the examples are kept small enough that the
whole module takes well under a minute on a warm cache.

This is how the pages keep their promises: a snippet that stopped working (an undefined name, a renamed
option) or a script that hangs (``vector_env(..., workers=2)`` without the ``__main__`` guard) fails here.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = sorted((ROOT / "docs").rglob("*.md")) + [ROOT / "README.md"]
TIMEOUT_S = 120
FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<ticks>`{3,})(?P<info>[^\n`]*)\n(?P<body>.*?)^(?P=indent)(?P=ticks)[ \t]*$",
                   re.M | re.S)
MARKER = re.compile(r"<!--\s*not-run\s*:(?P<reason>(?:(?!-->).)*)-->", re.S)
MARKER_BEFORE = re.compile(MARKER.pattern + r"\s*$", re.S)  # a marker that ends right before a fence


def _blocks(page: Path):
    """``(line, language, code, not_run_reason or None)`` of each fenced block of ``page``; the reason is that
    of a ``not-run`` marker right before the fence, blank lines apart ("" when the marker gives none)."""
    text = page.read_text()
    for m in FENCE.finditer(text):
        marker = MARKER_BEFORE.search(text, 0, m.start())
        lang = m.group("info").strip().split()[0] if m.group("info").strip() else ""
        body = "\n".join(line[len(m.group("indent")):] for line in m.group("body").splitlines())
        yield text.count("\n", 0, m.start()) + 1, lang, body, (marker.group("reason").strip() if marker else None)


def _python_blocks():
    for page in PAGES:
        for line, lang, code, reason in _blocks(page):
            if lang == "python":
                yield pytest.param(code, reason, id=f"{page.relative_to(ROOT)}:{line}")


BLOCKS = list(_python_blocks())


def test_the_pages_have_python_examples_and_every_marker_gives_a_reason():
    assert len(BLOCKS) >= 6
    assert sum(p.values[1] is None for p in BLOCKS) >= 5  # most of them run
    bad = []
    for page in PAGES:
        text = page.read_text()
        for m in MARKER.finditer(text):
            line = text.count("\n", 0, m.start()) + 1
            where = f"{page.relative_to(ROOT)}:{line}"
            if not m.group("reason").strip():
                bad.append(f"{where}: a not-run marker without a reason")
            rest = text[m.end():]
            nxt = re.match(r"\s*\n[ \t]*```python", rest)
            if nxt is None:
                bad.append(f"{where}: a not-run marker that is not right before a ```python block")
    assert not bad, "\n".join(bad)


def _run(code: str, tmp_path, timeout_s: float = TIMEOUT_S):
    """Run ``code`` as a script of its own in ``tmp_path``; the completed process (stdout and stderr as text)."""
    script = tmp_path / "example.py"
    script.write_text(code)
    path = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": path}
    return subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True,
                          timeout=timeout_s, env=env)


@pytest.mark.parametrize("code, reason", BLOCKS)
def test_docs_python_block_runs(code, reason, tmp_path):
    if reason is not None:
        pytest.skip(f"marked not-run: {reason}")
    out = _run(code, tmp_path)
    assert out.returncode == 0, (f"the example failed:\n{code}\n--- stdout\n{out.stdout[-3000:]}\n"
                                 f"--- stderr\n{out.stderr[-5000:]}")


TRAINING = [p for p in BLOCKS if re.search(r"\bPPO\(", p.values[0])]


def test_a_training_snippet_sizes_its_rollout_trains_in_seconds_and_shows_progress(tmp_path):
    """Regression (issue 52): the environment page's ``PPO("MlpPolicy", sb3_vec_env(8, ...))`` took SB3's defaults,
    163,840 transitions and 25,600 gradient steps per update over the 80 slots, and a reader who added
    ``learn(total_timesteps=2048)`` saw nothing for 15 minutes. Every ``PPO(...)`` of the pages sizes its rollout
    (``n_steps``, ``batch_size``) and prints its progress (``verbose=1``), and the runnable ones learn within 60 s
    and print SB3's table."""
    assert TRAINING, "no PPO(...) example in the pages"
    for param in TRAINING:
        code, reason = param.values
        calls = re.findall(r"\bPPO\((.*)\)", code)
        assert all("n_steps=" in c and "batch_size=" in c and "verbose=1" in c for c in calls), (param.id, calls)
        if reason is None:
            assert ".learn(" in code, param.id
            out = _run(code, tmp_path, timeout_s=60)
            assert out.returncode == 0, out.stderr[-3000:]
            assert "total_timesteps" in out.stdout, out.stdout[-3000:]


def test_the_readme_has_two_set_up_commands_an_example_episode_and_reads_its_table():
    """Regression (issue 52): the README had no RL code (a reader who came for the environment found none until
    getting_started.md) and its preset table used J_s and the presets' names before saying what they are. The
    README keeps exactly two set-up commands; a PettingZoo episode of the calibrated baseline follows them as
    example code (run by test_docs_python_block_runs), and the table's terms are explained before it."""
    readme = ROOT / "README.md"
    blocks = list(_blocks(readme))
    assert [lang for _, lang, _, _ in blocks if lang == "bash"] == ["bash", "bash"]  # the two set-up commands
    (example,) = [b for b in blocks if b[1] == "python"]
    line, _, code, reason = example
    text = readme.read_text()
    lines = text.splitlines()
    heading = next(lines[k] for k in range(line - 1, -1, -1) if lines[k].startswith("## "))
    assert heading.startswith("## Example") and reason is None
    assert "Example code, not a set-up step" in text
    assert 'as_policy("baseline")' in code and "crowd_v0.parallel_env(" in code and "while env.agents:" in code
    assert len([c for c in code.splitlines() if c.strip()]) <= 13
    assert text.index("## Set-up") < text.index("## Example") < text.index("## What it reproduces")
    table = text.index("| target (criterion) |")
    for term in ("**J_s = N/(Δt b)**", "**capacity**", "**Speed and density inside**", "**density in front**",
                 "**J(b) linear**", "**Lanes**", "**stalls**", "**smallest gap**", "**corridor runs**", "**ρ / v**",
                 "**J**", "**single file**", "**`calibrated`**", "**`joint`**", "**`paper`**", "**`recalibrated`**",
                 "**`vision`**"):
        assert -1 < text.find(term) < table, term
