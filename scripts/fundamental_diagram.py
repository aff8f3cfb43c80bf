#!/usr/bin/env python
"""Fundamental diagram (speed and specific flow vs density) of a bottleneck run, computed with PedPy (see --help).

Runs one bottleneck run or reads an exported trajectory; writes a PNG and a CSV.
"""
import sys

from crowd_env.cli.fundamental_diagram import main

if __name__ == "__main__":
    sys.exit(main())
