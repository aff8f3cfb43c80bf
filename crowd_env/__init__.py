"""crowd_env: a PettingZoo/Gymnasium multi-agent pedestrian environment running the Kabalan et al. (2016)
crowd model (rigid disks, Frémond non-smooth collisions, eikonal navigation, social repulsion)."""
__version__ = "0.1.0"
from . import registration as _registration  # noqa: F401  (gymnasium ids; registers lazily)
from .compilation import announce_compilation as _announce_compilation

_announce_compilation()  # one line on stderr when the kernels are first compiled on a machine
