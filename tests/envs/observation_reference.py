"""Frozen observations, rewards and spaces of ``crowd_v0`` (``tests/data/observation_reference.npz``).

The arrays were written by the environment as it was before observations became components and the
reward named terms (the compiled 17-argument ``_observe`` kernel and the one-loop ``DefaultReward``);
``tests/envs/test_components.py`` checks that today's environment gives them bitwise. Rewrite them only
on purpose: ``PYTHONPATH=. python tests/envs/observation_reference.py``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

PATH = Path(__file__).resolve().parents[1] / "data" / "observation_reference.npz"

# name -> (environment options, steps, action rule); every case is reset with seed 3
CASES = {
    "bottleneck_world": (dict(scenario="seyfried_bottleneck", scenario_options={"width_m": 1.0, "n_pedestrians": 12},
                              frame_skip=5), 8, "random"),
    "bottleneck_egocentric": (dict(scenario="seyfried_bottleneck", scenario_options={"width_m": 1.0, "n_pedestrians": 12},
                                   frame_skip=5, observation_frame="egocentric", n_neighbors=3, n_rays=4,
                                   controlled=0.5), 12, "random"),
    "bottleneck_exits": (dict(scenario="seyfried_bottleneck", scenario_options={"width_m": 1.2, "n_pedestrians": 8},
                              frame_skip=10, heading_target="desired_direction"), 70, "walk"),  # 6 leave
    "bidirectional_world": (dict(scenario="corridor_bidirectional", scenario_options={"n_per_direction": 4},
                                 frame_skip=5, n_neighbors=4, n_rays=6), 6, "random"),
    "bidirectional_egocentric": (dict(scenario="corridor_bidirectional", scenario_options={"n_per_direction": 4},
                                      frame_skip=5, observation_frame="egocentric"), 6, "random"),
    "periodic_world": (dict(scenario="periodic_corridor", scenario_options={"length_m": 8.0, "n_pedestrians": 10},
                            frame_skip=5), 6, "walk"),
    "no_neighbors_no_rays": (dict(scenario="seyfried_bottleneck", scenario_options={"n_pedestrians": 6},
                                  frame_skip=5, n_neighbors=0, n_rays=0, observation_frame="egocentric"), 5, "random"),
}


def rollout(options: dict, steps: int, rule: str) -> dict:
    """Observation rows (steps + 1 blocks of the live agents, pedestrian order), rewards, the agents'
    pedestrian indices per row, and the observation space's bounds."""
    from crowd_env.envs import crowd_v0

    env = crowd_v0.parallel_env(**options)
    obs, _ = env.reset(seed=3)
    rng = np.random.default_rng(1)
    a_max = 0.8 * env.action_max_m_s
    ed = env.observation_layout["desired_direction"]
    rows, who, step_of, rewards, reward_who = [], [], [], [], []

    def keep(o, k, ended=()):  # long rollouts: every 10th step's rows and the last row of an agent that left
        for a in env.possible_agents:
            if a in o and (steps <= 20 or k % 10 == 0 or a in ended):
                rows.append(o[a])
                who.append(int(a[4:]))
                step_of.append(k)

    keep(obs, 0)
    for k in range(1, steps + 1):
        if not env.agents:
            break
        if rule == "walk":
            actions = {a: np.clip(1.3 * obs[a][ed].astype(np.float64), -a_max, a_max) for a in env.agents}
        else:
            draws = rng.uniform(-1.0, 1.5, size=(len(env.possible_agents), 2))
            actions = {a: draws[i] for i, a in enumerate(env.possible_agents) if a in env.agents}
        obs, rew, term, *_ = env.step(actions)
        keep(obs, k, [a for a, t in term.items() if t])
        for a in env.possible_agents:
            if a in rew:
                rewards.append(rew[a])
                reward_who.append(int(a[4:]))
    space = env.observation_space(env.possible_agents[0])
    return {"obs": np.array(rows, np.float32), "who": np.array(who), "step": np.array(step_of),
            "rewards": np.array(rewards, np.float64), "reward_who": np.array(reward_who),
            "low": space.low, "high": space.high}


def main() -> None:
    out = {}
    for name, (options, steps, rule) in CASES.items():
        for key, value in rollout(options, steps, rule).items():
            out[f"{name}/{key}"] = value
    np.savez_compressed(PATH, **out)
    print(f"wrote {PATH} ({PATH.stat().st_size} bytes)")


if __name__ == "__main__":
    main()
