#!/usr/bin/env python
"""Calibrate the social force A, B (and optionally λ, τ, desired speeds) against Seyfried et al. (2009).

Same as the console command ``crowd-calibrate`` (see --help): ``grid`` for the ε_T surface of Kabalan
et al. (2016) Fig. 10, ``optimize`` for Eq. 25. Ray by default (local, or ``--address`` of a cluster).
"""
import sys

from crowd_env.cli.calibrate import main

if __name__ == "__main__":
    sys.exit(main())
