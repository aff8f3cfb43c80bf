"""The benchmark of learned policies against the calibrated model: see ``crowd-benchmark --help``."""
from crowd_env.cli.benchmark import main

if __name__ == "__main__":
    raise SystemExit(main())
