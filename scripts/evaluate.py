"""Evaluate policies on the same scenarios and seeds: see ``crowd-evaluate --help``."""
from crowd_env.cli.evaluate import main

if __name__ == "__main__":
    raise SystemExit(main())
