"""Write an MP4 or GIF of a rollout or a trajectory file: see ``crowd-video --help``."""
from crowd_env.cli.video import main

if __name__ == "__main__":
    raise SystemExit(main())
