"""Reproduce the collision calibration of Kabalan et al. (2016), Section 3 (Figs. 5-7).

Usage: ``crowd-collision-figures --out DIR`` writes PNGs and prints the numbers
(:mod:`crowd_env.experiments.validation.collision`).
"""
from __future__ import annotations

import argparse

from ..experiments.validation.collision import make_figures


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="crowd-collision-figures", description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/paper_collision", help="output directory for the PNGs")
    args = parser.parse_args(argv)
    for p in make_figures(args.out):
        print("wrote", p)
    return 0
