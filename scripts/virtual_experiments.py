"""Every shipped experiment as it was run, beside its data. See ``crowd-virtual-experiments --help``."""
from crowd_env.cli.virtual_experiments import main

if __name__ == "__main__":
    raise SystemExit(main())
