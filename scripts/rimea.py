"""The RiMEA verification tests on crowd_env (and JuPedSim beside it): see ``crowd-rimea --help``."""
from crowd_env.cli.rimea import main

if __name__ == "__main__":
    raise SystemExit(main())
