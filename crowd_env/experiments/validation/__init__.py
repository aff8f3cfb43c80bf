"""The model against experiments: ``bottleneck`` (the Seyfried et al. 2009 reproduction of Kabalan et al. 2016,
Section 4, in the task format the calibration and generalisation share), ``calibration`` (Section 4.1.2: errors,
objective, grid, optimiser, landscape, preset table), ``fundamental_diagram`` and ``periodic`` (the corridor and
single-file density sweeps), ``generalisation``, ``rimea`` (the RiMEA suite), ``soak`` (invariants under load),
``collision`` (Section 3, Figs. 5-7) and ``stall_study``."""
