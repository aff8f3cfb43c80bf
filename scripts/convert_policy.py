"""Convert a trained model to a policy file (.npz), the format to share: see ``crowd-convert-policy --help``."""
from crowd_env.cli.convert_policy import main

if __name__ == "__main__":
    raise SystemExit(main())
