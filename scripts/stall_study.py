"""Why the paper preset clogs under pressure and the calibrated one does not: see ``crowd-stall-study --help``."""
from crowd_env.cli.stall_study import main

if __name__ == "__main__":
    raise SystemExit(main())
