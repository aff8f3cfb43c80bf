"""The reference results of learned policies against the calibrated model: see ``crowd-reference-results --help``."""
from crowd_env.cli.reference_results import main

if __name__ == "__main__":
    raise SystemExit(main())
