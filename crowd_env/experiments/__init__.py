"""The experiment layer: simulations run and measured the way the commands and tests need them.

``runner`` runs a scenario to the end (or a stall) and measures it (Kabalan et al. 2016, Eq. 22);
``bottleneck`` is the Seyfried bottleneck pipeline (Section 4: one run, a sweep, the summary) in the one
task format; ``store`` the one run store and ``backends`` the one executor (Ray, process pool, serial)
of the reproduction, the calibration and the generalisation; ``calibration`` fits the social force
(Section 4.1.2, Eq. 23-25); ``recording`` records trajectories of a run; ``generalisation``, ``soak``,
``stall_study``, ``evaluation`` (the harness that compares policies) and ``training`` (PPO) are the
other pipelines. Commands (:mod:`crowd_env.cli`) call these; :mod:`crowd_env.analysis` only measures.
"""
