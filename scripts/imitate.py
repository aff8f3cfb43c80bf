"""Demonstrations from recorded trajectories, and the human policy from the recordings: see ``crowd-imitate --help``."""
from crowd_env.cli.imitate import main

if __name__ == "__main__":
    raise SystemExit(main())
