"""Checkpoints of long runs (RunCheckpoint): a run killed part-way and resumed from its checkpoint gives the
uninterrupted run's result to the last bit, through the compiled rollout and the staged path alike."""
import json

import numpy as np
import pytest

from crowd_env.errors import InputError
from crowd_env.experiments.running.recording import record_run
from crowd_env.experiments.running.runner import RunCheckpoint, read_checkpoint
from crowd_env.scenarios import make_scenario
from crowd_env.walking.agent import SocialForceAgent


class Killed(Exception):
    pass


def _run(checkpoint=None, kill_after_calls=None, compiled=True):
    """A 0.8 m bottleneck with 60 pedestrians for 8 s (a jam at the door: contacts every step), recorded at
    10 frames/s, in chunks of 40 steps; ``kill_after_calls``: the progress callback raises after that many
    calls, as a killed process would stop."""
    sc = make_scenario("seyfried_bottleneck", width_m=0.8, n_pedestrians=60, seed=3)
    calls = [0]

    def progress(sim):
        calls[0] += 1
        if kill_after_calls is not None and calls[0] >= kill_after_calls:
            raise Killed

    state = sc.make_state(rng=np.random.default_rng(3))
    result, traj = record_run(sc, SocialForceAgent(sc.navigation()), state=state, frame_rate_per_s=10.0, max_time_s=8.0,
                              chunk_steps=40, progress=progress, checkpoint=checkpoint, compiled=compiled)
    return result, traj, state


def _same(a, b):
    (ra, ta, sa), (rb, tb, sb) = a, b
    assert ra.n_steps == rb.n_steps and ra.simulated_time_s == rb.simulated_time_s
    assert np.array_equal(ra.crossing_times_s, rb.crossing_times_s)
    assert ra.min_gap_m == rb.min_gap_m and ra.n_evacuated == rb.n_evacuated
    for k in ra.density_per_m2:
        assert np.array_equal(ra.density_per_m2[k], rb.density_per_m2[k], equal_nan=True)
    for f in ("frame", "id", "x_m", "y_m", "heading_rad"):
        assert np.array_equal(getattr(ta, f), getattr(tb, f)), f
    assert np.array_equal(sa.position_m, sb.position_m) and np.array_equal(sa.active, sb.active)


@pytest.mark.parametrize("compiled", [True, False])
def test_a_killed_run_resumes_to_the_last_bit(tmp_path, compiled):
    whole = _run(compiled=compiled)
    assert whole[0].n_steps == 800 and len(whole[0].crossing_times_s) > 5
    path = str(tmp_path / "run.checkpoint.pkl")
    # every_s = 0: a checkpoint before every chunk (compiled) or step (Python); killed after the 5th
    with pytest.raises(Killed):
        _run(RunCheckpoint(path, key="bottleneck-0.8-60-3", every_s=0.0), kill_after_calls=5, compiled=compiled)
    kept = read_checkpoint(path)
    assert kept["key"] == "bottleneck-0.8-60-3" and 0 < kept["done"] < 800
    cp = RunCheckpoint(path, key="bottleneck-0.8-60-3", every_s=0.0)
    resumed = _run(cp)
    _same(resumed, whole)
    assert cp.resumed_wall_s > 0.0 and resumed[0].wall_time_s >= cp.resumed_wall_s
    assert not (tmp_path / "run.checkpoint.pkl").exists()  # removed once the run is over
    with pytest.raises(Killed):
        _run(RunCheckpoint(path, key="k", every_s=0.0), kill_after_calls=2, compiled=compiled)
    kept_by_caller = RunCheckpoint(path, key="k", every_s=0.0, remove_when_done=False)
    _same(_run(kept_by_caller), whole)
    assert (tmp_path / "run.checkpoint.pkl").exists()  # the caller removes it once it has kept the result
    kept_by_caller.remove()
    assert not (tmp_path / "run.checkpoint.pkl").exists()


def test_another_runs_checkpoint_is_not_resumed(tmp_path):
    path = str(tmp_path / "run.checkpoint.pkl")
    with pytest.raises(Killed):
        _run(RunCheckpoint(path, key="a", every_s=0.0), kill_after_calls=3)
    with pytest.warns(RuntimeWarning, match="made for another run"):
        other = _run(RunCheckpoint(path, key="b", every_s=0.0))
    _same(other, _run())
    with pytest.raises(Killed):
        _run(RunCheckpoint(path, key="a", every_s=0.0), kill_after_calls=3)
    fresh = RunCheckpoint(path, key="a", every_s=0.0, resume=False)  # a fresh run ignores a kept one
    _same(_run(fresh), _run())
    assert fresh.resumed_wall_s == 0.0
    with pytest.raises(InputError, match="checkpoint every_s must be a finite number >= 0"):
        RunCheckpoint(path, key="a", every_s=-1.0)


def test_rimea_suite_keeps_checkpoints_beside_its_runs(tmp_path, monkeypatch):
    """The suite gives crowd_env's runs a checkpoint beside the kept run, keyed by the run's settings and
    resumed only with --resume."""
    from crowd_env.experiments.validation.rimea import suite

    seen = []

    def fake_runner(sc, *, seed, max_time_s, checkpoint=None):
        seen.append(checkpoint)
        raise Killed

    monkeypatch.setattr(suite, "_runner", lambda backend: fake_runner)
    for resume in (False, True):
        with pytest.raises(Killed):
            suite.run_suite(["1"], quick=True, out_dir=str(tmp_path), resume=resume, progress=None)
    assert [c.resume for c in seen] == [False, True] and not any(c.remove_when_done for c in seen)
    assert seen[0].path == suite.run_path(str(tmp_path), "1", next(iter(_variants())), "crowd_env") + ".checkpoint.pkl"
    assert json.loads(seen[0].key)["test"] == "1" and seen[0].key == seen[1].key


def _variants():
    from crowd_env.experiments.validation.rimea.base import select_tests

    return select_tests(["1"])[0].scenarios(True, 0)


def test_a_checkpoint_signed_under_another_key_is_refused_unread(tmp_path, monkeypatch):
    """A checkpoint signed by another account's crowd_env (its key elsewhere) is refused: UntrustedFileError,
    nothing in it runs (a plain pickle planted as the checkpoint: tests/test_untrusted_files.py)."""
    import pickle

    from crowd_env.errors import UntrustedFileError
    from crowd_env.files import SECRET_FILE_ENV, write_signed_atomic
    from tests.conftest import CodeRunningPayload

    path, flag = tmp_path / "run.checkpoint.pkl", tmp_path / "ran.flag"
    monkeypatch.setenv(SECRET_FILE_ENV, str(tmp_path / "someone_else.key"))
    write_signed_atomic(path, pickle.dumps({"key": "a", "evil": CodeRunningPayload(flag)}))
    monkeypatch.setenv(SECRET_FILE_ENV, str(tmp_path / "mine.key"))
    with pytest.raises(UntrustedFileError, match="run.checkpoint.pkl was not signed with this account's key"):
        _run(RunCheckpoint(str(path), key="a", every_s=0.0))
    assert not flag.exists()
