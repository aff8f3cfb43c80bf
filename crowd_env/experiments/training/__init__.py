"""RL training and evaluation: ``ppo`` (Stable-Baselines3 PPO shared by all controlled pedestrians), ``marl``
(MAPPO / IPPO through TorchRL), ``rllib`` (PPO through RLlib), ``imitation`` (behaviour cloning of the calibrated
agent), ``evaluation`` (any policy through the same scenarios, seeds and measures) and ``reference_results``
(learned policies against the calibrated model, ``crowd-reference-results``). Policy files are
:mod:`crowd_env.envs.policy_files`, where the environment loads them."""
