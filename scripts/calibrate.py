"""Calibrate the social force against Seyfried et al. (2009): see ``crowd-calibrate --help``."""
from crowd_env.cli.calibrate import main

if __name__ == "__main__":
    raise SystemExit(main())
