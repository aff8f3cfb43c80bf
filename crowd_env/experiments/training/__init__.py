"""RL training: ``ppo`` (Stable-Baselines3 PPO shared by all controlled pedestrians), ``marl``
(MAPPO / IPPO through TorchRL), ``rllib`` (PPO through RLlib), ``imitation`` (behaviour cloning of the calibrated
agent) and ``reference_results``
(learned policies against the calibrated model, ``crowd-reference-results``). The evaluation harness that
runs any policy is :mod:`crowd_env.experiments.running.evaluation`; policy files are
:mod:`crowd_env.envs.policy_files`, where the environment loads them."""
