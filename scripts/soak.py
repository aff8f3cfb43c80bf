"""Soak test over every registered scenario with random and adversarial actions: see ``crowd-soak --help``."""
from crowd_env.cli.soak import main

if __name__ == "__main__":
    raise SystemExit(main())
