"""The model on bottleneck set-ups other than Seyfried et al.'s (2009): see ``crowd-generalise --help``."""
from crowd_env.cli.generalisation import main

if __name__ == "__main__":
    raise SystemExit(main())
