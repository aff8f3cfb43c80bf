"""Train one policy shared by all controlled pedestrians with MAPPO or IPPO (TorchRL): see ``crowd-train-mappo --help``."""
from crowd_env.cli.train_mappo import main

if __name__ == "__main__":
    raise SystemExit(main())
