"""How human is a policy? See ``crowd-scorecard --help``."""
from crowd_env.cli.scorecard import main

if __name__ == "__main__":
    raise SystemExit(main())
