"""The cold start shared by a pool's workers (crowd_env.experiments.running.warmup): the shipped plan names what the
compiled rollout compiles (so the workers' parts spare the rollout every one of them), its types are written back
exactly, and a pool on an empty numba cache compiles the parts in its workers before the runs."""
import json
import os
import subprocess
import sys

import pytest
from numba.core import types

from crowd_env.compilation import MESSAGE
from crowd_env.errors import InputError
from crowd_env.experiments.running import compile_plan, warmup
from crowd_env.experiments.running.compile_plan import PARTS

_ROLLOUT_COMPILE = r"""
import json, sys
from numba.core import dispatcher, event, sigutils
from numba.core.caching import NullCache
from crowd_env.experiments.running import rollout, warmup
from crowd_env.experiments.running.compile_plan import PARTS
from crowd_env.experiments.running.runner import run_scenario
from crowd_env.scenarios import make_scenario
from crowd_env.walking.agent import SocialForceAgent

for k in range(len(PARTS)):
    warmup.compile_part(k)  # from the package's cache when it holds them
requested, compiled = set(), []
original = dispatcher.Dispatcher.compile

def spy(self, sig):
    args, _ = sigutils.normalize_signature(sig)
    requested.add(f"{self.py_func.__module__}.{self.py_func.__name__}{tuple(args)}")
    return original(self, sig)

stack = []

class Listener(event.Listener):  # what compiles inside the rollout's own compilation
    def on_start(self, ev):
        name = f"{ev.data['dispatcher'].py_func.__module__}.{ev.data['dispatcher'].py_func.__name__}"
        if stack or name.endswith(".rollout_steps"):
            compiled.append(name)
            stack.append(name)

    def on_end(self, ev):
        if stack:
            stack.pop()

dispatcher.Dispatcher.compile = spy
event.register("numba:compile", Listener())
rollout.rollout_steps._cache = NullCache()  # compile the rollout here, whatever the cache holds
scenario = make_scenario("seyfried_bottleneck", width_m=1.0, n_pedestrians=4, seed=0)
result = run_scenario(scenario, SocialForceAgent(scenario.navigation()), state=scenario.make_state(), max_time_s=2.0)
print(json.dumps({"requested": sorted(requested), "compiled": compiled}))
"""


def _planned():
    return [(kernel, sig) for part in PARTS for kernel, sigs in part for sig in sigs]


def test_the_plan_is_what_the_rollout_compiles():
    """The rollout compiled anew after the plan's parts: it asks every planned kernel for its planned signature,
    compiles none of them again and no other kernel of crowd_env (the parts spared it all of them), only itself."""
    done = subprocess.run([sys.executable, "-c", _ROLLOUT_COMPILE], capture_output=True, text=True,
                          env={**os.environ, "CROWD_ENV_QUIET": "1"})
    assert done.returncode == 0, done.stderr[-3000:]
    seen = json.loads(done.stdout.strip().splitlines()[-1])
    names = {f"{k.py_func.__module__}.{k.__name__}" for k, _ in _planned()}
    assert seen["compiled"][0] == "crowd_env.experiments.running.rollout.rollout_steps"
    again = sorted(names & set(seen["compiled"]))
    assert not again, f"compiled again by the rollout (the plan is stale: regenerate it, see compile_plan): {again}"
    missed = sorted({n for n in seen["compiled"][1:] if n.startswith("crowd_env.")})
    assert not missed, f"kernels of crowd_env the rollout compiled that the plan misses (regenerate it): {missed}"
    planned = [f"{k.py_func.__module__}.{k.__name__}{tuple(s)}" for k, s in _planned()]
    unused = [key for key in planned if key not in seen["requested"]]
    assert not unused, f"planned but not asked for by the rollout (a stale plan): {unused}"


def test_the_parts_are_balanced_and_disjoint():
    """Two parts, no kernel in both, and neither more than 1.5 times the other in the measured times the
    generator wrote beside them."""
    assert len(PARTS) == 2
    kernels = [k for part in PARTS for k, _ in part]
    assert len(kernels) == len(set(kernels)) > 2
    with open(compile_plan.__file__, encoding="utf-8") as f:
        seconds = [float(line.split("#")[1].split()[0]) for line in f if "s of compilation, measured" in line]
    assert len(seconds) == 2 and max(seconds) <= 1.5 * min(seconds)


def test_type_source_writes_every_planned_type_back_exactly():
    namespace = {**vars(types), **vars(compile_plan)}
    for kernel, sig in _planned():
        assert eval(warmup.tuple_source(sig), namespace) == tuple(sig), kernel  # noqa: S307 (our own text)
    readonly = types.Array(types.float64, 2, "C", readonly=True)
    assert eval(warmup.type_source(readonly), namespace) == readonly
    assert warmup.tuple_source((types.int64,)) == "(int64,)"
    with pytest.raises(InputError, match="no source form"):
        warmup.type_source(types.unicode_type)


_TINY_KERNELS = ("import numba\n\n@numba.njit(cache=True)\ndef one(x):\n    return x + 1.0\n\n"
                 "@numba.njit(cache=True)\ndef two(x):\n    return x * 2\n")

_POOL_WARM_UP = r"""
import json, multiprocessing, sys
multiprocessing.set_start_method("fork")  # the workers inherit the plan set below, whatever this Python's default
sys.path.insert(0, sys.argv[1])
import tiny_kernels
from numba.core import types
from crowd_env.experiments.running import compile_plan, warmup
from crowd_env.experiments.running.backends import ProcessBackend

compile_plan.PARTS = (((tiny_kernels.one, ((types.float64,),)),), ((tiny_kernels.two, ((types.int64,),)),))
warmup.rollout_is_cached = lambda: False
backend = ProcessBackend(2)
with backend:
    runs = list(backend.imap_unordered(abs, [-1]))
print(json.dumps({"runs": runs, "warmed": backend._warmed}))
"""


def _tiny_kernels_plan(tmp_path):
    """A plan of two small kernels of a module written under ``tmp_path`` (compiled in seconds)."""
    (tmp_path / "tiny_kernels.py").write_text(_TINY_KERNELS, encoding="utf-8")
    import importlib

    sys.modules.pop("tiny_kernels", None)
    sys.path.insert(0, str(tmp_path))
    try:
        tiny_kernels = importlib.import_module("tiny_kernels")
    finally:
        sys.path.remove(str(tmp_path))
    return ((tiny_kernels.one, ((types.float64,),)), (tiny_kernels.two, ((types.int64,),)))


def test_a_pool_on_a_cold_cache_compiles_the_parts_in_its_workers(tmp_path):
    """A process pool's first runs on an empty numba cache (a fresh process, a plan of two tiny kernels): the
    parts compiled in its workers before the run (the cache then holds both kernels), the notice said once."""
    (tmp_path / "tiny_kernels.py").write_text(_TINY_KERNELS, encoding="utf-8")
    cache = tmp_path / "cache"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    env.pop("CROWD_ENV_QUIET", None)
    done = subprocess.run([sys.executable, "-c", _POOL_WARM_UP, str(tmp_path)], capture_output=True, text=True,
                          env=env)
    assert done.returncode == 0, done.stderr[-3000:]
    seen = json.loads(done.stdout.strip().splitlines()[-1])
    assert seen == {"runs": [[-1, True, 1]], "warmed": True}
    index = sorted(p.name.split(".")[1].split("-")[0] for p in cache.rglob("*.nbi"))
    assert index == ["one", "two"], index
    assert done.stderr.count(MESSAGE) == 1


def test_nothing_to_warm_on_one_worker_or_with_the_rollout_cached(monkeypatch):
    calls = []
    monkeypatch.setattr(warmup, "rollout_is_cached", lambda: False)
    assert not warmup.warm_up(lambda fn, items: calls.append(1), 1)  # one worker: nothing to share
    monkeypatch.setattr(warmup, "rollout_is_cached", lambda: True)
    assert not warmup.warm_up(lambda fn, items: calls.append(1), 2)  # cached: nothing to compile
    assert calls == []


def test_a_stale_signature_warns_and_the_rest_is_served(tmp_path, monkeypatch):
    one, two = _tiny_kernels_plan(tmp_path)
    stale = (one[0], ((types.unicode_type, types.unicode_type),))  # 'one' takes one argument
    monkeypatch.setattr(compile_plan, "PARTS", ((stale, two),))
    with pytest.warns(RuntimeWarning, match="compile plan out of date.*one"):
        assert warmup.compile_part(0) == 1


def test_the_rollout_is_cached_after_a_run():
    from crowd_env.scenarios import make_scenario
    from crowd_env.experiments.running.runner import run_scenario
    from crowd_env.walking.agent import SocialForceAgent

    scenario = make_scenario("seyfried_bottleneck", width_m=1.0, n_pedestrians=4, seed=0)
    run_scenario(scenario, SocialForceAgent(scenario.navigation()), state=scenario.make_state(), max_time_s=1.0)
    assert warmup.rollout_is_cached()
