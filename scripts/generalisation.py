#!/usr/bin/env python
"""Run a preset on bottleneck set-ups other than Seyfried 2009's and measure it (see --help).

Same as the console command ``crowd-generalise``.
"""
import sys

from crowd_env.cli.generalisation import main

if __name__ == "__main__":
    sys.exit(main())
