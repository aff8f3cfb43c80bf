"""Fundamental diagram of a bottleneck run, computed with PedPy: see ``crowd-fundamental-diagram --help``."""
from crowd_env.cli.fundamental_diagram import main

if __name__ == "__main__":
    raise SystemExit(main())
