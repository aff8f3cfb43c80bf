"""Running and storing runs: ``runner`` (a scenario to the end or a stall, measured like the experiment,
Kabalan et al. 2016, Eq. 22), ``rollout`` (many steps in one compiled call), ``store`` (the run store, resumable),
``backends`` (the one executor: Ray, a process pool or serial), ``warmup`` with its generated ``compile_plan`` (a
pool's workers share a cold start's compilation), ``recording`` (a run with its trajectories), ``evaluation`` (the
harness: any policy through the same scenarios, seeds and measures)."""
