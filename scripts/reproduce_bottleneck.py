"""Reproduce Kabalan et al. (2016) Section 4 on the Seyfried bottleneck: see ``crowd-bottleneck --help``."""
from crowd_env.cli.reproduce_bottleneck import main

if __name__ == "__main__":
    raise SystemExit(main())
