"""The collision figures of Kabalan et al. (2016), Section 3: see ``crowd-collision-figures --help``."""
from crowd_env.cli.paper_collision_figures import main

if __name__ == "__main__":
    raise SystemExit(main())
