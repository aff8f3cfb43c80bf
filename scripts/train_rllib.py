"""Train one PPO policy shared by all controlled pedestrians with RLlib: see ``crowd-train-rllib --help``."""
from crowd_env.cli.train_rllib import main

if __name__ == "__main__":
    raise SystemExit(main())
