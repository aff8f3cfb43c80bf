#!/usr/bin/env python
"""Reproduce Kabalan et al. (2016) Section 4 on the Seyfried 2009 bottleneck (see --help).

Same as the console command ``crowd-bottleneck``.
"""
import sys

from crowd_env.cli.reproduce_bottleneck import main

if __name__ == "__main__":
    sys.exit(main())
