"""The native vector environment against the PettingZoo environment it batches.

Copy c of ``vector_env(K, **options)`` reset with seed s must give exactly what
``crowd_v0.parallel_env(**options)`` reset with seed s + c gives for the same actions (observations,
rewards, terminations, truncations), through agents leaving, padding slots and automatic resets; plus
the SB3 and TorchRL views, and the errors for bad input.
"""
from __future__ import annotations

import numpy as np
import pytest

from crowd_env.envs import crowd_v0
from crowd_env.envs.vector import CrowdVectorEnv, vector_env
from crowd_env.errors import ActionError, EnvOptionError, EnvStateError, WorkerError

OPTIONS = {"scenario": "seyfried_bottleneck", "scenario_options": {"width_m": 1.0, "n_pedestrians": 5},
           "frame_skip": 10, "max_steps": 100, "controlled": 4}


def _walk(obs_rows, layout, rng, scale=1.6):
    """Walk along e_d with some noise (so some agents leave early, others are truncated)."""
    e_d = obs_rows[:, layout["desired_direction"]].astype(np.float64)
    return np.clip(scale * e_d + rng.normal(0.0, 0.5, e_d.shape), -2.5, 2.5)


def test_each_copy_matches_the_pettingzoo_env_on_its_seed_through_deaths_and_resets():
    K, seed = 3, 11
    vec = vector_env(K, **OPTIONS, reward_terms_in_infos=True)
    refs = [crowd_v0.parallel_env(**OPTIONS, reward_terms_in_infos=True) for _ in range(K)]
    A = vec.n_agents
    obs, infos = vec.reset(seed=seed)
    ref_obs = [r.reset(seed=seed + c)[0] for c, r in enumerate(refs)]
    layout = refs[0].observation_layout
    rng = np.random.default_rng(0)
    episodes_done = np.zeros(K, int)
    returns = np.zeros((K, A))
    saw_padding = False
    for _ in range(260):
        for c, r in enumerate(refs):  # the vector's observations are the reference's (zeros for padding)
            for a_pos, agent in enumerate(r.possible_agents):
                row = obs[c * A + a_pos]
                if agent in ref_obs[c] and infos["alive"][c * A + a_pos]:
                    np.testing.assert_array_equal(row, ref_obs[c][agent])
                else:
                    assert not row.any()
        actions = _walk(obs, layout, rng)
        actions[~infos["alive"]] = np.nan  # padding slots' actions are ignored, whatever they are
        obs, rew, term, trunc, infos = vec.step(actions)
        saw_padding |= bool((~infos["alive"]).any() and not (term | trunc)[~infos["alive"]].all())
        for c, r in enumerate(refs):
            live = list(r.agents)
            acts = {a: actions[c * A + r.possible_agents.index(a)] for a in live}
            o, rr, te, tr, ri = r.step(acts)
            for a in live:
                i = c * A + r.possible_agents.index(a)
                assert rew[i] == rr[a] and term[i] == te[a] and trunc[i] == tr[a]
                assert infos["reward_terms"][i].tolist() == ri[a]["reward_terms"]  # each term, to the bit
                returns[c, r.possible_agents.index(a)] += rr[a]
                if te[a] or tr[a]:
                    np.testing.assert_array_equal(infos["final_obs"][i], o[a])
                    assert infos["_final_obs"][i] and infos["episode_ended"][i]
                    assert infos["episode_return"][i] == pytest.approx(returns[c, r.possible_agents.index(a)])
                    returns[c, r.possible_agents.index(a)] = 0.0
            slots = np.arange(c * A, (c + 1) * A)
            padding = slots[~infos["acted"][slots]]
            assert not rew[padding].any() and not infos["reward_terms"][padding].any()
            if not r.agents:  # the copy reset in the same step; so does the reference
                episodes_done[c] += 1
                assert term[padding].all() and not infos["episode_ended"][padding].any()
                assert infos["alive"][slots].all()
                ref_obs[c] = r.reset()[0]
            else:
                assert not (term | trunc)[padding].any()
                ref_obs[c] = o
    assert (episodes_done >= 2).all() and saw_padding
    assert vec.reward_term_names == refs[0].reward_term_names == ("progress", "contact_percussion", "time", "exit")
    assert infos["reward_terms"].shape == (K * A, 4)


@pytest.mark.parametrize("option", [{}, {"reward_terms_in_infos": False}])
def test_reward_terms_stay_out_of_the_vector_infos_when_the_copies_do_not_report_them(option):
    vec = vector_env(2, **OPTIONS, **option)
    _, infos = vec.reset(seed=0)
    _, _, _, _, after = vec.step(np.zeros((vec.num_envs, 2)))
    assert vec.reward_term_names is None and "reward_terms" not in infos and "reward_terms" not in after


def test_vector_state_and_spaces():
    vec = vector_env(2, **OPTIONS)
    with pytest.raises(EnvStateError, match="reset\\(\\) before step\\(\\)"):
        vec.step(np.zeros((vec.num_envs, 2)))
    obs, _ = vec.reset(seed=0)
    assert vec.num_envs == 2 * 4 and obs.shape == vec.observation_space.shape and obs.dtype == np.float32
    st = vec.state()
    assert st.shape == (2,) + vec.single_state_space.shape
    np.testing.assert_array_equal(st[vec.slot_copy][4], st[1])


def test_bad_actions_and_mismatched_copies_are_refused_by_name():
    vec = vector_env(2, **OPTIONS)
    vec.reset(seed=0)
    with pytest.raises(ActionError, match=r"shape \(8, 2\)"):
        vec.step(np.zeros((7, 2)))
    bad = np.zeros((8, 2))
    bad[3, 0] = np.nan
    with pytest.raises(ActionError, match=r"non-finite action\(s\) in live slot\(s\) \[3\]"):
        vec.step(bad)
    bad[3, 0] = 9.0
    with pytest.raises(ActionError, match=r"slot\(s\) \[3\] outside the action space"):
        vec.step(bad)
    with pytest.raises(ActionError, match=r"^complex action\(s\): a velocity intent is two real numbers"):
        vec.step(np.zeros((8, 2)) + 0.5j)  # issue 52: numpy dropped the imaginary part with only a warning
    with pytest.raises(EnvOptionError, match="copy 1 does not match copy 0: its observation space"):
        CrowdVectorEnv([crowd_v0.parallel_env(**OPTIONS), crowd_v0.parallel_env(**OPTIONS, n_neighbors=2)])
    with pytest.raises(EnvOptionError, match="copy 1 does not match copy 0: its number of agents"):
        CrowdVectorEnv([crowd_v0.parallel_env(**OPTIONS), crowd_v0.parallel_env(**{**OPTIONS, "controlled": 2})])
    with pytest.raises(EnvOptionError, match="copies must be an integer >= 1"):
        vector_env(0, **OPTIONS)
    with pytest.raises(EnvOptionError, match="one seed per copy"):
        vec.reset(seed=[1, 2, 3])


def test_sb3_view_reports_agent_episodes_and_trains():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO

    from crowd_env.envs.sb3 import sb3_vec_env

    vec = sb3_vec_env(2, seed=3, **{**OPTIONS, "max_steps": 15})
    obs = vec.reset()
    assert obs.shape == (8, vec.observation_space.shape[0])
    n_agent_episodes = n_done = 0
    for _ in range(40):
        vec.step_async(np.tile([1.0, 0.0], (8, 1)))
        obs, rew, dones, infos = vec.step_wait()
        n_done += int(dones.sum())
        n_agent_episodes += sum("episode" in i for i in infos)
        for i in np.flatnonzero(dones):
            assert "terminal_observation" in infos[i] and "TimeLimit.truncated" in infos[i]
    # nobody reaches the exit in 1.5 s: every agent is truncated at steps 15 and 30, copies reset, no padding
    assert n_agent_episodes == n_done == 2 * 4 * 2
    model = PPO("MlpPolicy", vec, n_steps=32, batch_size=64, n_epochs=1, device="cpu")
    model.learn(256)
    assert model.num_timesteps >= 256 and len(model.ep_info_buffer) > 0


def test_torchrl_wraps_the_vector_env():
    pytest.importorskip("torchrl")
    from torchrl.envs import GymWrapper

    vec = vector_env(2, **{**OPTIONS, "max_steps": 10})
    env = GymWrapper(vec, device="cpu")
    assert tuple(env.batch_size) == (8,)
    td = env.rollout(25, break_when_any_done=False)
    assert tuple(td.shape) == (8, 25)
    assert td["next", "done"].sum().item() >= 8  # every slot ended at least one episode (max_steps 10)
    assert td["next", "alive"].dtype.is_floating_point is False


# ---------------------------------------------------------------- worker processes
def _reward_failing_at_step_3(env, agent_ids, info):
    """A reward function (module level, so workers can load it) that fails on the third step."""
    if env._steps >= 3:
        raise ValueError("reward broke on purpose")
    return np.zeros(len(agent_ids))


def test_workers_give_bitwise_the_serial_results_and_close_stops_them():
    K, seed = 3, 5
    serial = vector_env(K, **OPTIONS, reward_terms_in_infos=True)  # the terms' columns in the shared buffer too
    par = vector_env(K, workers=2, **OPTIONS, reward_terms_in_infos=True)
    procs = par._pool.procs[1:]  # group 0 steps in this process, group 1 in a worker process
    assert len(procs) == 1 and all(p.is_alive() for p in procs)
    layout = serial.envs[0].observation_layout
    rng = np.random.default_rng(1)
    out_s, out_p = serial.reset(seed=seed), par.reset(seed=seed)
    n_resets = 0
    for _ in range(120):
        for a, b in zip(out_s, out_p):
            for x, y in (zip(a.values(), b.values()) if isinstance(a, dict) else [(a, b)]):
                assert x.dtype == y.dtype and x.tobytes() == y.tobytes()
        actions = _walk(out_s[0], layout, rng)
        out_s, out_p = serial.step(actions), par.step(actions)
        assert out_p[4]["reward_terms"].shape == (par.num_envs, 4)
        n_resets += int(out_s[2][~out_s[4]["acted"]].any())
    assert n_resets >= 1  # copies reset inside the workers too
    np.testing.assert_array_equal(serial.state(), par.state())
    assert par.get_attr("time_s") == serial.get_attr("time_s")
    par.set_attr("max_steps", [7, 8, 9])
    assert par.call("__getattribute__", "max_steps") == (7, 8, 9)
    par.close()
    assert not any(p.is_alive() for p in procs)
    par.close()  # twice is fine
    with pytest.raises(EnvStateError, match="closed"):
        par.step(np.zeros((par.num_envs, 2)))


@pytest.mark.parametrize("copy, where", [(0, "this process"), (1, r"pid \d+")])
def test_an_exception_in_a_group_is_raised_with_its_traceback(copy, where):
    # copy 0 steps in this process (group 0), copy 1 in the worker process: both report the same way
    vec = vector_env(2, workers=2, **OPTIONS)
    vec.set_attr("reward_fn", _reward_failing_at_step_3, copies=[copy])
    vec.reset(seed=0)
    actions = np.zeros((vec.num_envs, 2))
    vec.step(actions)
    vec.step(actions)
    with pytest.raises(WorkerError, match=rf"worker {copy} \({where}, copies {copy}\.\.{copy}\) raised ValueError: "
                                          r"reward broke on purpose") as info:
        vec.step(actions)
    assert "_reward_failing_at_step_3" in str(info.value) and "Traceback" in str(info.value)
    assert isinstance(info.value.__cause__, ValueError)
    with pytest.raises(EnvStateError, match="a worker failed earlier"):
        vec.step(actions)
    vec.close()


def test_a_dead_worker_is_an_error_not_a_hang():
    import os
    import signal

    vec = vector_env(2, workers=2, **OPTIONS)
    vec.reset(seed=0)
    procs = vec._pool.procs[1:]
    victim = procs[0]
    os.kill(victim.pid, signal.SIGKILL)
    victim.join(10)
    with pytest.raises(WorkerError, match=r"worker 1 \(pid \d+, copies 1\.\.1\) (died|is gone)"):
        vec.step(np.zeros((vec.num_envs, 2)))
    vec.close()
    assert not any(p.is_alive() for p in procs)


@pytest.mark.parametrize("options, match", [
    ({"workers": 0}, "workers must be an integer >= 1, got 0"),
    ({"workers": True}, "workers must be an integer >= 1, got True"),
    ({"workers": 1.5}, "workers must be an integer >= 1, got 1.5"),
    ({"workers": 3}, "workers = 3 exceeds the 2 copies"),
    ({"workers": 2, "start_method": "teleport"}, "start_method must be one of"),
])
def test_bad_worker_options_are_refused_by_name(options, match):
    with pytest.raises(EnvOptionError, match=match):
        vector_env(2, **options, **OPTIONS)


def test_sb3_view_with_workers():
    pytest.importorskip("stable_baselines3")
    from crowd_env.envs.sb3 import sb3_vec_env

    vec = sb3_vec_env(2, seed=3, workers=2, **OPTIONS)
    obs = vec.reset()
    assert obs.shape == (8, vec.observation_space.shape[0])
    vec.step_async(np.tile([1.0, 0.0], (8, 1)))
    vec.step_wait()
    assert vec.get_attr("max_steps", indices=[0, 5]) == [100, 100]
    vec.set_attr("max_steps", 50, indices=[5])
    assert vec.get_attr("max_steps") == [100] * 4 + [50] * 4
    assert vec.env_method("__getattribute__", "n_pedestrians", indices=[1, 6]) == [5, 5]
    vec.close()


def test_a_script_without_the_main_guard_fails_fast_saying_what_to_do(tmp_path):
    """Regression (issue 37): vector_env(..., workers=2) at a script's top level blocked for ever in
    Process.start(): the spawned worker re-runs the script, fails there and never reads its arguments. Now the
    parent raises WorkerError at once, and both errors name the ``__main__`` guard."""
    import subprocess
    import sys
    import time

    script = tmp_path / "unguarded.py"
    script.write_text("from crowd_env.envs.vector import vector_env\n"
                      f"vec = vector_env(2, workers=2, **{OPTIONS!r})\n"
                      "print('started')\n")
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert time.perf_counter() - t0 < 60
    assert out.returncode != 0 and "started" not in out.stdout
    assert "crowd_env.errors.WorkerError: worker 1" in out.stderr and "died while starting" in out.stderr
    assert 'if __name__ == "__main__":' in out.stderr.split("WorkerError")[-1]
    # the worker's own error says the same (it made the vector environment while importing the script)
    assert "was made while a 'spawn' worker process was importing the main module" in out.stderr

    guarded = tmp_path / "guarded.py"
    guarded.write_text("from crowd_env.envs.vector import vector_env\n"
                       "if __name__ == '__main__':\n"
                       f"    vec = vector_env(2, workers=2, **{OPTIONS!r})\n"
                       "    vec.reset(seed=0)\n"
                       "    vec.close()\n"
                       "    print('started')\n")
    out = subprocess.run([sys.executable, str(guarded)], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert out.returncode == 0 and "started" in out.stdout, out.stderr


def test_a_worker_that_cannot_load_its_copies_is_a_worker_error_at_start():
    """Start-up waits for each worker's 'ready': a worker whose copies fail to load reports it with its
    traceback, as a WorkerError of the constructor, instead of dying before the first step."""
    envs = [crowd_v0.parallel_env(**OPTIONS) for _ in range(2)]
    envs[1].extra = _LoadsInTheParentOnly()  # copy 1 goes to worker 1
    with pytest.raises(WorkerError, match=r"worker 1 \(pid \d+, copies 1\.\.1\) raised RuntimeError: no copies "
                                          r"here") as info:
        CrowdVectorEnv(envs, workers=2)
    assert "_loads_in_the_parent_only" in str(info.value)


class _LoadsInTheParentOnly:
    def __reduce__(self):
        return _loads_in_the_parent_only, ()


def _loads_in_the_parent_only():
    import multiprocessing

    if multiprocessing.parent_process() is not None:
        raise RuntimeError("no copies here")
    return _LoadsInTheParentOnly()


def test_vector_workers_run_numpy_s_blas_on_one_thread():
    """crowd_env.threads: the copies stepped in a worker process see one BLAS thread (the reward pays the
    count); group 0 steps in this process, which keeps its own."""
    from tests.envs.user_reward_term import blas_threads_reward

    vec = vector_env(2, workers=2, **OPTIONS, reward_fn=blas_threads_reward)
    try:
        vec.reset(seed=0)
        _, rewards, _, _, infos = vec.step(np.zeros((vec.num_envs, 2)))
        worker_slots = (vec.slot_copy == 1) & infos["acted"]
        assert worker_slots.any() and set(rewards[worker_slots].tolist()) == {1.0}
    finally:
        vec.close()



def test_the_compiled_action_check_agrees_with_numpy_on_bounds_nan_and_dead_slots():
    """``actions_within`` (both APIs' fast check) against the plain numpy reading of the same rule."""
    from crowd_env.envs.crowd_v0 import _EVERY_ROW, actions_within

    rng = np.random.default_rng(3)
    for trial in range(400):
        n = int(rng.integers(0, 12))
        a = rng.uniform(-3.0, 3.0, (n, 2))
        if n and trial % 3 == 0:
            a[rng.integers(n), rng.integers(2)] = rng.choice([np.nan, np.inf, -np.inf, 2.5, -2.5, 2.5000001])
        live = rng.random(n) < 0.7
        want_all = bool(np.all(np.abs(a) <= 2.5))  # NaN compares False
        want_live = bool(np.all(np.abs(a[live]) <= 2.5))
        assert actions_within(a, 2.5, _EVERY_ROW) is want_all
        assert actions_within(a, 2.5, live) is want_live
