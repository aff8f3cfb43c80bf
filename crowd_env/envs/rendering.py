"""Matplotlib rendering of the crowd: walls, exits, measurement lines and pedestrians as oriented disks.

``rgb_array`` draws off-screen with the Agg canvas (no pyplot, no display needed) and returns an
``(H, W, 3)`` uint8 image. ``human`` opens a pyplot window and updates it each call; when matplotlib's
backend is non-interactive (headless machines, where it falls back to Agg) it warns once and draws
off-screen only, returning None as PettingZoo expects, instead of failing.
"""
from __future__ import annotations

import warnings

import numpy as np

__all__ = ["CrowdRenderer", "CONTROLLED_COLOR", "BACKGROUND_COLOR"]

CONTROLLED_COLOR = (0.12, 0.47, 0.71)  # learned / controlled pedestrians: blue
BACKGROUND_COLOR = (0.65, 0.65, 0.65)  # background-policy pedestrians: grey
_NON_INTERACTIVE = {"agg", "cairo", "pdf", "pgf", "ps", "svg", "template"}


def _interactive_backend() -> bool:
    import matplotlib

    backend = str(matplotlib.get_backend()).lower()
    return backend not in _NON_INTERACTIVE and "inline" not in backend


class CrowdRenderer:
    """Draws a :class:`~crowd_env.core.geometry.Geometry` and a :class:`~crowd_env.core.state.CrowdState`."""

    def __init__(self, geometry, controlled_mask: np.ndarray, mode: str, *, width_in: float = 8.0, dpi: int = 80,
                 fps: float = 10.0):
        self.geometry = geometry
        self.controlled = np.asarray(controlled_mask, dtype=bool)
        self.mode = mode
        self.fps = float(fps)
        self.window = False
        x0, y0, x1, y1 = geometry.bounds
        pad = 0.3
        aspect = (y1 - y0 + 2 * pad) / (x1 - x0 + 2 * pad)
        size = (width_in, float(np.clip(width_in * aspect, 1.5, 2.0 * width_in)))
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
        self.disks = EllipseCollection(np.ones(n), np.ones(n), np.zeros(n), units="xy", offsets=np.zeros((n, 2)),
                                       offset_transform=ax.transData, facecolors=self._colors,
                                       edgecolors="k", linewidths=0.5, zorder=2)
        ax.add_collection(self.disks)
        self.noses = LineCollection(np.zeros((n, 2, 2)), colors="k", linewidths=1.0, zorder=3)
        ax.add_collection(self.noses)
        self.title = ax.set_title("", fontsize=9)

    def draw(self, state, time_s: float, n_agents: int):
        """Update the artists for ``state``; returns the RGB image (rgb_array) or None (human)."""
        if self.mode == "human" and not self.window:
            return None  # headless fallback: nothing to show
        active = state.active
        pos = state.position_m
        r = state.radius_m
        d = 2.0 * r
        self.disks.set_offsets(pos)
        self.disks.set_widths(d)
        self.disks.set_heights(d)
        colors = self._colors.copy()
        colors[~active, 3] = 0.0
        self.disks.set_facecolors(colors)
        edge = np.zeros((active.shape[0], 4))
        edge[:, 3] = active
        self.disks.set_edgecolors(edge)
        tip = pos + r[:, None] * np.column_stack([np.cos(state.heading_rad), np.sin(state.heading_rad)])
        seg = np.stack([pos, tip], axis=1)[active]
        self.noses.set_segments(seg)
        self.title.set_text(f"t = {time_s:6.2f} s   on floor: {int(active.sum())}   live agents: {n_agents}")
        if self.window:
            import matplotlib.pyplot as plt

            self.fig.canvas.draw_idle()
            plt.pause(1.0 / max(self.fps, 1e-3))
            return None
        self.fig.canvas.draw()
        return np.asarray(self.fig.canvas.buffer_rgba())[..., :3].copy()

    def close(self) -> None:
        if self.window:
            import matplotlib.pyplot as plt

            plt.close(self.fig)
        self.fig = None
