"""The experiment layer: simulations run and measured the way the commands and tests need them, by purpose.

- :mod:`~crowd_env.experiments.running`: running and storing runs: a scenario run to the end or a stall and
  measured (Kabalan et al. 2016, Eq. 22), compiled rollouts, the run store, the one executor (Ray, a process
  pool or serial), trajectory recording, the evaluation harness that runs any policy.
- :mod:`~crowd_env.experiments.training`: RL training (PPO through Stable-Baselines3, MAPPO/IPPO through TorchRL,
  PPO through RLlib, behaviour cloning) and the reference results of learned policies against the calibrated
  model.
- :mod:`~crowd_env.experiments.validation`: the model against experiments: the Seyfried bottleneck reproduction
  (Section 4), the calibration (Section 4.1.2, Eq. 23-25, one home), the fundamental diagram, generalisation,
  the RiMEA suite, the soak, the collision experiments (Section 3), the stall study.
- :mod:`~crowd_env.experiments.output`: videos, the commands' tables, the harness's report.

Inside the layer, training and validation use output and running, output uses running, and running uses
neither (an import-linter contract).

Commands (:mod:`crowd_env.cli`) call these; :mod:`crowd_env.analysis` only measures.
"""
