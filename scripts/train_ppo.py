"""Train one PPO policy shared by all controlled pedestrians: see ``crowd-train-ppo --help``."""
from crowd_env.cli.train_ppo import main

if __name__ == "__main__":
    raise SystemExit(main())
