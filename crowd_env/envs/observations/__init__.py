"""Per-agent observation vectors of the crowd environment, built for all agents at once.

One observation is a flat ``float32`` vector in one of two frames (the environment's
``observation_frame`` option; :data:`FRAMES`). With ``k`` neighbours and ``R`` rays:

``"world"`` (default): vectors in the scenario's x, y axes; ``7 + 5 k + R`` entries, in this order
(:data:`OBSERVATION_FIELDS`; :func:`observation_layout` gives the slices):

==========================  =====  ====================================================================
field                       size   meaning (units)
==========================  =====  ====================================================================
``velocity``                2      own velocity (u_x, u_y) in m/s
``heading``                 2      (cos θ, sin θ) of the own heading θ
``desired_direction``       2      e_d = −∇T/‖∇T‖ of the (own destination's) eikonal field at the own
                                   position (unit vector)
``travel_time``             1      T at the own position: remaining travel time to the nearest exit (to
                                   the own destination exit in scenarios with destinations) in s at the
                                   field's wavefront speed (1 m/s by default, so numerically the
                                   geodesic distance in m); 0 inside an exit
``neighbors``               4 k    for each of the k nearest other pedestrians within
                                   ``neighbor_radius_m`` (nearest first): (x_j − x_i, y_j − y_i) in m and
                                   (u_j − u_i) in m/s; zeros where there are fewer than k
``neighbor_mask``           k      1 for a real neighbour in that slot, 0 for padding
``wall_rays``               R      distance in m from the own centre to the first wall along R rays at
                                   angles θ + 2π r / R (r = 0 … R−1; ray 0 points along the heading),
                                   capped at ``ray_range_m``
==========================  =====  ====================================================================

``"egocentric"``: every vector in the pedestrian's body frame: x forward along its heading θ, y to its
left (a world vector v becomes R(−θ) v). The heading itself is then the frame, so the field is left
out: ``5 + 5 k + R`` entries (:data:`EGOCENTRIC_OBSERVATION_FIELDS`): ``velocity`` (forward, left
speed), ``desired_direction`` (e_d in the body frame), ``travel_time``, ``neighbors`` (relative
positions and velocities in the body frame), ``neighbor_mask``, ``wall_rays`` (unchanged: the rays
are already relative to the heading). Nothing in it depends on the scenario's orientation or
position: a rotated and shifted copy of a scenario gives the same observations
(``tests/envs/test_frames.py``).

Neighbours are every other active pedestrian, controlled or background.

Components
    The observation is a list of named components (the environment's ``observation_components``
    option; default :data:`DEFAULT_COMPONENTS`), each in its own module of this package with its
    blocks, sizes, bounds, frame handling and compiled kernel: :mod:`.velocity`, :mod:`.heading`,
    :mod:`.desired_direction`, :mod:`.travel_time`, :mod:`.neighbors` (``neighbors`` and
    ``neighbor_mask``), :mod:`.wall_rays`, and, off by default, :mod:`.free_distance` (the free walk
    ahead) and :mod:`.local_density` (a disc density). A new one subclasses
    :class:`~.base.ObservationComponent` in a module of its own and is named in the option as
    ``"module:Class"`` (or passed as an object): nothing else changes. The assembler
    (:class:`~.assembler.ObservationBuilder`) computes what components share once per step (the field's
    bilinear sampling, one k-nearest search on a cell grid,
    :func:`crowd_env.core.neighbors.grid_k_nearest`, the headings' cos and sin:
    :class:`~.base.ObservationContext`) and lets each fill its columns for all agents at once; nothing
    loops over agents in Python. The built-in components are written in one compiled call
    (:func:`~.assembler._write_builtins`, the kernels their ``write`` calls), a component of another module
    from Python after it.
"""
from __future__ import annotations

from .assembler import (COMPONENTS, DEFAULT_COMPONENTS, ObservationBuilder, observation_fields, observation_layout,
                        observation_size, resolve_components)
from .base import (FRAMES, ObservationComponent, ObservationContext, ObservationField, ObservationSpec, check_frame,
                   to_body_frame, to_world_frame)

__all__ = ["FRAMES", "OBSERVATION_FIELDS", "EGOCENTRIC_OBSERVATION_FIELDS", "ObservationField", "observation_fields",
           "observation_layout", "observation_size", "check_frame", "ObservationBuilder", "ObservationComponent",
           "ObservationContext", "ObservationSpec", "COMPONENTS", "DEFAULT_COMPONENTS", "resolve_components",
           "to_body_frame", "to_world_frame"]

# The blocks of the default observation, world and egocentric frames.
OBSERVATION_FIELDS: tuple = observation_fields("world")
EGOCENTRIC_OBSERVATION_FIELDS: tuple = observation_fields("egocentric")
