"""Matplotlib rendering of the crowd: walls, exits, measurement lines, pedestrians as oriented disks and
contact percussions.

``rgb_array`` draws off-screen with the Agg canvas (no pyplot, no display needed) and returns an
``(H, W, 3)`` uint8 image. ``human`` opens a pyplot window and updates it each call; when matplotlib's
backend is non-interactive (headless machines, where it falls back to Agg) it warns once and draws
off-screen only, returning None as PettingZoo expects, instead of failing.

One drawing function, :meth:`CrowdRenderer.draw_frame`, serves ``env.render()`` (through
:meth:`CrowdRenderer.draw`, from the simulator's state) and the videos of
:mod:`crowd_env.experiments.output.video` (from a rollout, or from a saved trajectory file):

- pedestrians are disks of their radius, learned (controlled) ones in :data:`CONTROLLED_COLOR` (blue),
  background ones in :data:`BACKGROUND_COLOR` (grey);
- each pedestrian's heading is a black line from its centre to its rim (none when the heading is
  unknown, NaN, as in trajectory files without a heading column);
- contact percussions, when given (:class:`ContactPercussions` collects them from the simulator's
  sub-steps), are lines from centre to centre (pedestrian-pedestrian) or from the centre to the closest
  point of the wall segment (pedestrian-wall), drawn over the disks; their width and colour (yellow to dark
  red, :data:`PERCUSSION_CMAP`) grow with the magnitude ‖P_n‖ of the normal percussion summed over the
  simulator steps since the previous frame, up to ``percussion_scale_kg_m_s`` (20 kg m/s by default),
  beyond which they stay at the widest and darkest.
"""
from __future__ import annotations

import warnings

import numpy as np

from ..errors import InputError
from ..core.body import body_circles, circle_count
from ..core.checks import check_integer, check_number
from ..core.periodic import minimum_image_dx

__all__ = ["CrowdRenderer", "ContactPercussions", "contact_segments", "CONTROLLED_COLOR", "BACKGROUND_COLOR",
           "PERCUSSION_CMAP"]

CONTROLLED_COLOR = (0.12, 0.47, 0.71)  # learned / controlled pedestrians: blue
BACKGROUND_COLOR = (0.65, 0.65, 0.65)  # background-policy pedestrians: grey
PERCUSSION_CMAP = "YlOrRd"  # contact percussions: yellow (small) to dark red (>= the scale)
_NON_INTERACTIVE = {"agg", "cairo", "pdf", "pgf", "ps", "svg", "template"}


def _interactive_backend() -> bool:
    import matplotlib

    backend = str(matplotlib.get_backend()).lower()
    return backend not in _NON_INTERACTIVE and "inline" not in backend


class ContactPercussions:
    """Substep hook (``env.substep_hooks.append(hook)``) summing the normal contact percussions of the
    simulator steps since the last :meth:`take`, per contact: pedestrian pair (i, j), or pedestrian i and
    wall segment w (j = −1, as in :class:`~crowd_env.core.simulator.StepResult`).

    :meth:`take` returns ``(i, j, wall, percussion)`` arrays (‖P_n‖ summed, kg m/s) for
    :meth:`CrowdRenderer.draw_frame` and starts a new sum (:meth:`peek` keeps it, :meth:`clear` only starts
    it). :meth:`add` takes one step's arrays directly. The environment clears its own at the start of every
    environment step, so ``env.render()`` shows the contacts of the last step only, drawn between the
    positions at its end (older contacts, drawn between the current positions of pedestrians that have
    since moved apart, would be long lines across the floor).
    """

    def __init__(self):
        self._parts: list = []

    def __call__(self, env, result, prev_position_m=None, prev_time_s=None) -> None:
        self.add(result.contact_i, result.contact_j, result.contact_wall, result.percussion_normal)

    def add(self, contact_i, contact_j, contact_wall, percussion_normal) -> None:
        j = np.asarray(contact_j, dtype=np.int64)
        ijw = np.column_stack([np.asarray(contact_i, dtype=np.int64), j,
                               np.where(j < 0, np.asarray(contact_wall, dtype=np.int64), -1)])
        self._parts.append((ijw, np.abs(np.asarray(percussion_normal, dtype=np.float64))))

    def clear(self) -> None:
        """Forget the contacts collected so far (a new sum starts)."""
        self._parts = []

    def take(self) -> tuple:
        """``(i, j, wall, percussion)`` of the contacts since the last call (empty arrays when none); resets."""
        summed = self.peek()
        self.clear()
        return summed

    def peek(self) -> tuple:
        """What :meth:`take` would return, without starting a new sum."""
        parts = self._parts
        ijw = np.concatenate([a for a, _ in parts]).reshape(-1, 3) if parts else np.zeros((0, 3), np.int64)
        p = np.concatenate([b for _, b in parts]) if parts else np.zeros(0)
        keep = p > 0.0
        keys, inverse = np.unique(ijw[keep], axis=0, return_inverse=True)
        total = np.bincount(inverse.ravel(), weights=p[keep], minlength=keys.shape[0])
        keys = keys.reshape(-1, 3)
        return keys[:, 0], keys[:, 1], keys[:, 2], total


def contact_segments(position_m, active, walls, contacts, period_m: float = 0.0) -> tuple:
    """End points ``(K, 2, 2)`` and percussions ``(K,)`` of the contact lines: centre to centre for a pair,
    centre to the closest point of wall segment ``walls[w]`` ((S, 4) rows x0 y0 x1 y1) for j = −1.
    ``contacts``: ``(i, j, wall, percussion)`` arrays (:meth:`ContactPercussions.take`). Contacts of a
    pedestrian no longer ``active`` (it left during the frame) are left out. ``period_m`` > 0 (a periodic
    corridor): a pair across the seam is drawn from i to the nearest image of j."""
    i, j, w, p = (np.asarray(a) for a in contacts)
    if not (i.shape == j.shape == w.shape == p.shape and i.ndim == 1):
        raise InputError(f"contacts must be four equal-length 1-D arrays (i, j, wall, percussion), got shapes "
                         f"{[a.shape for a in (i, j, w, p)]}")
    pos = np.asarray(position_m, dtype=np.float64)
    n = pos.shape[0]
    i = i.astype(np.int64)
    j = j.astype(np.int64)
    w = w.astype(np.int64)
    walls = np.asarray(walls, dtype=np.float64).reshape(-1, 4)
    bad = (i < 0) | (i >= n) | (j < -1) | (j >= n) | ((j < 0) & ((w < 0) | (w >= walls.shape[0])))
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InputError(f"contact {k} (i={int(i[k])}, j={int(j[k])}, wall={int(w[k])}) names no pedestrian of "
                         f"0..{n - 1} or wall segment of 0..{walls.shape[0] - 1}")
    act = np.asarray(active, dtype=bool)
    keep = act[i] & np.where(j >= 0, act[np.maximum(j, 0)], True)
    i, j, w, p = i[keep], j[keep], w[keep], p[keep].astype(np.float64)
    a = pos[i]
    b = pos[np.maximum(j, 0)].copy()
    if period_m > 0.0:
        b[:, 0] = a[:, 0] + minimum_image_dx(np.ascontiguousarray(b[:, 0] - a[:, 0]), float(period_m))
    on_wall = j < 0
    if on_wall.any():
        seg = walls[w[on_wall]]
        s0, d = seg[:, :2], seg[:, 2:] - seg[:, :2]
        t = np.einsum("ij,ij->i", a[on_wall] - s0, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
        b[on_wall] = s0 + np.clip(t, 0.0, 1.0)[:, None] * d  # closest point of the segment
    return np.stack([a, b], axis=1), p


class CrowdRenderer:
    """Draws a :class:`~crowd_env.core.geometry.Geometry` and a crowd (see the module docstring).

    ``controlled_mask`` (N,) marks the learned pedestrians. ``pixel_multiple`` > 1 makes the image's width
    and height multiples of it (16 for H.264 video, which would otherwise be rescaled); the default keeps
    the figure size of ``width_in`` × ``dpi`` pixels wide. ``percussion_scale_kg_m_s``: the percussion at
    which contact lines reach their widest and darkest. ``body_depth_m``: the bodies' depth
    (:mod:`crowd_env.core.body`; each body is drawn as its three circles), 0 for the paper's disks.
    """

    def __init__(self, geometry, controlled_mask: np.ndarray, mode: str, *, width_in: float = 8.0, dpi: int = 80,
                 fps: float = 10.0, pixel_multiple: int = 1, percussion_scale_kg_m_s: float = 20.0,
                 body_depth_m: float = 0.0):
        check_integer("pixel_multiple", pixel_multiple, error=InputError, minimum=1)
        check_number("percussion_scale_kg_m_s", percussion_scale_kg_m_s, error=InputError, positive=True)
        self.body_depth_m = check_number("body_depth_m", body_depth_m, error=InputError, minimum=0.0)
        self._circles = circle_count(self.body_depth_m)
        self.geometry = geometry
        self.controlled = np.asarray(controlled_mask, dtype=bool)
        self.mode = mode
        self.fps = float(fps)
        self.percussion_scale_kg_m_s = float(percussion_scale_kg_m_s)
        self.window = False
        x0, y0, x1, y1 = geometry.bounds
        pad = 0.3
        aspect = (y1 - y0 + 2 * pad) / (x1 - x0 + 2 * pad)
        size = (width_in, float(np.clip(width_in * aspect, 1.5, 2.0 * width_in)))
        if pixel_multiple > 1:
            m = int(pixel_multiple)
            size = tuple(max(m, m * round(v * dpi / m)) / dpi for v in size)
        if mode == "human" and _interactive_backend():
            import matplotlib.pyplot as plt

            plt.ion()
            self.fig = plt.figure(figsize=size, dpi=dpi)
            self.window = True
        else:
            if mode == "human":
                warnings.warn("render_mode='human' needs an interactive matplotlib backend; the current one "
                              "is non-interactive (headless?), so frames are drawn off-screen only. Use "
                              "render_mode='rgb_array' to get images.", RuntimeWarning, stacklevel=3)
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure

            self.fig = Figure(figsize=size, dpi=dpi)
            FigureCanvasAgg(self.fig)
        self.ax = self.fig.add_axes([0.01, 0.01, 0.98, 0.9])
        self._static(pad)

    def _static(self, pad: float) -> None:
        from matplotlib import colormaps
        from matplotlib.collections import EllipseCollection, LineCollection
        from matplotlib.patches import Polygon as MplPolygon

        ax = self.ax
        g = self.geometry
        x0, y0, x1, y1 = g.bounds
        ax.set_xlim(x0 - pad, x1 + pad)
        ax.set_ylim(y0 - pad, y1 + pad)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        for poly in getattr(g.walkable_area, "geoms", [g.walkable_area]):
            ax.add_patch(MplPolygon(np.asarray(poly.exterior.coords), closed=True, facecolor=(0.97, 0.97, 0.95),
                                    edgecolor="none", zorder=0))
        for ex in g.exits:
            for poly in getattr(ex, "geoms", [ex]):
                ax.add_patch(MplPolygon(np.asarray(poly.exterior.coords), closed=True, facecolor=(0.75, 0.9, 0.75),
                                        edgecolor="none", zorder=0.5))
        walls = np.asarray(g.walls).reshape(-1, 2, 2)
        ax.add_collection(LineCollection(walls, colors="k", linewidths=2.0, zorder=1))
        for line in g.measurement_lines.values():
            line = np.asarray(line)
            ax.plot(line[:, 0], line[:, 1], ls="--", color=(0.8, 0.3, 0.3), lw=1.0, zorder=1)
        n = self.controlled.shape[0]
        self._colors = np.zeros((n, 4))
        self._colors[:, :3] = np.where(self.controlled[:, None], CONTROLLED_COLOR, BACKGROUND_COLOR)
        self._colors[:, 3] = 1.0
        self._colors = np.repeat(self._colors, self._circles, axis=0)  # each body's circles in a row
        n = n * self._circles
        self.disks = EllipseCollection(np.ones(n), np.ones(n), np.zeros(n), units="xy", offsets=np.zeros((n, 2)),
                                       offset_transform=ax.transData, facecolors=self._colors,
                                       edgecolors="k", linewidths=0.5, zorder=2)
        ax.add_collection(self.disks)
        self.noses = LineCollection(np.zeros((n, 2, 2)), colors="k", linewidths=1.0, zorder=3)
        ax.add_collection(self.noses)
        self._cmap = colormaps[PERCUSSION_CMAP]
        self.contacts = LineCollection(np.zeros((0, 2, 2)), capstyle="round", zorder=4)
        ax.add_collection(self.contacts)
        self.title = ax.set_title("", fontsize=9)

    def draw(self, state, time_s: float, n_agents: int, contacts=None):
        """Draw a :class:`~crowd_env.core.state.CrowdState` (what ``env.render()`` calls); returns the RGB image
        (rgb_array) or None (human). ``contacts``: see :meth:`draw_frame`."""
        title = f"t = {time_s:6.2f} s   on floor: {int(state.active.sum())}   live agents: {n_agents}"
        return self.draw_frame(state.position_m, state.radius_m, state.heading_rad, state.active,
                               contacts=contacts, title=title)

    def draw_frame(self, position_m, radius_m, heading_rad, active, *, contacts=None, title: str = ""):
        """Draw one frame of the N pedestrians of ``controlled_mask``: ``position_m`` (N, 2), ``radius_m`` (N,),
        ``heading_rad`` (N,; NaN: no heading line), ``active`` (N,) bool (inactive ones are not drawn);
        ``contacts``: ``(i, j, wall, percussion)`` arrays (:meth:`ContactPercussions.take`) or None (no
        contact lines); ``title`` above the floor. Returns the ``(H, W, 3)`` uint8 image, or None in human
        mode."""
        if self.mode == "human" and not self.window:
            return None  # headless fallback: nothing to show
        n = self.controlled.shape[0]
        pos = np.asarray(position_m, dtype=np.float64)
        r = np.asarray(radius_m, dtype=np.float64)
        r = np.full(n, float(r)) if r.ndim == 0 else r
        heading = np.asarray(heading_rad, dtype=np.float64)
        active = np.asarray(active, dtype=bool)
        if pos.shape != (n, 2) or r.shape != (n,) or heading.shape != (n,) or active.shape != (n,):
            raise InputError(f"the renderer draws {n} pedestrians: position_m must be ({n}, 2), radius_m, "
                             f"heading_rad and active ({n},); got {pos.shape}, {r.shape}, {heading.shape}, "
                             f"{active.shape}")
        if self._circles == 1:
            centre, d = pos, 2.0 * r
        else:  # NaN headings (recordings) draw no shoulders
            centre, rc, _ = body_circles(pos, heading, r, np.arange(n, dtype=np.int64), self.body_depth_m)
            d = 2.0 * rc
        shown = np.repeat(active, self._circles)
        self.disks.set_offsets(centre)
        self.disks.set_widths(d)
        self.disks.set_heights(d)
        colors = self._colors.copy()
        colors[~shown, 3] = 0.0
        self.disks.set_facecolors(colors)
        edge = np.zeros((shown.shape[0], 4))
        edge[:, 3] = shown
        self.disks.set_edgecolors(edge)
        tip = pos + r[:, None] * np.column_stack([np.cos(heading), np.sin(heading)])
        seg = np.stack([pos, tip], axis=1)[active & np.isfinite(heading)]
        self.noses.set_segments(seg)
        if contacts is None:
            self.contacts.set_segments(np.zeros((0, 2, 2)))
        else:
            segs, p = contact_segments(pos, active, self.geometry.walls, contacts,
                                       getattr(self.geometry, "period_x_m", 0.0))
            level = np.minimum(p / self.percussion_scale_kg_m_s, 1.0)
            self.contacts.set_segments(segs)
            self.contacts.set_color(self._cmap(0.3 + 0.7 * level))
            self.contacts.set_linewidths(0.8 + 3.2 * level)
        self.title.set_text(title)
        if self.window:
            import matplotlib.pyplot as plt

            self.fig.canvas.draw_idle()
            plt.pause(1.0 / max(self.fps, 1e-3))
            return None
        self.fig.canvas.draw()
        return np.asarray(self.fig.canvas.buffer_rgba())[..., :3].copy()

    def pixel_of(self, points_m) -> np.ndarray:
        """Image pixel ``(column, row)`` (row 0 at the top) of the points ``(K, 2)`` in metres, as the images
        of :meth:`draw_frame` show them."""
        self.ax.apply_aspect()  # the equal-aspect box is otherwise only placed when drawn
        xy = self.ax.transData.transform(np.asarray(points_m, dtype=np.float64).reshape(-1, 2))
        height = self.fig.canvas.get_width_height()[1]
        return np.column_stack([xy[:, 0], height - xy[:, 1]])

    def close(self) -> None:
        if self.window:
            import matplotlib.pyplot as plt

            plt.close(self.fig)
        self.fig = None
