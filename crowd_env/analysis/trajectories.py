"""Trajectories in PedPy's formats: hold, export, read back, and measure with PedPy.

Interoperability with PedPy (https://pedpy.readthedocs.io), the Jülich analysis library:

- :class:`Trajectories` holds long-format rows (frame, id, x, y, heading) at a constant frame rate
  (PedPy's time is ``frame / frame_rate``), e.g. every k-th step of h (25 fps = every 4th step of
  h = 0.01 s, :func:`steps_per_frame`); :func:`crowd_env.experiments.running.recording.record_run` records one
  from a run of the runner;
- :meth:`Trajectories.write_txt` writes the whitespace text format that
  ``pedpy.load_trajectory_from_txt`` reads (``#framerate: 25.0`` header, columns
  ``id frame x/m y/m z/m`` plus ``heading/rad``, which PedPy ignores); :meth:`Trajectories.read_txt`
  reads it back (no PedPy needed); :meth:`Trajectories.to_pedpy` / :meth:`Trajectories.from_pedpy`
  convert to and from ``pedpy.TrajectoryData``;
- :func:`write_geometry` / :func:`read_geometry` store the walkable area (WKT), exits, measurement
  lines (end points) and areas (WKT) as JSON, plus the walkable area alone as a ``.wkt`` file;
  :func:`pedpy_walkable_area`, :func:`pedpy_measurement_line`, :func:`pedpy_measurement_area`
  convert a :class:`~crowd_env.core.geometry.Geometry`'s parts;
- :func:`fundamental_diagram_data`: classic density, mean speed and ρ·v per frame in a measurement
  area, computed by PedPy.

PedPy is an optional dependency (``pip install 'crowd_env[analysis]'``); only the functions that
build PedPy objects import it.
"""
from __future__ import annotations

from crowd_env.errors import InputError, MissingDependencyError, MissingFileError, NotFoundError, TrajectoryFormatError
from crowd_env.files import write_atomic

import gzip
import io
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import shapely

from ..core.checks import check_number
from .recorder import TrajectoryRecorder

__all__ = ["TrajectoryFormatError", "Trajectories", "require_pedpy", "steps_per_frame", "write_geometry",
           "read_geometry", "geometry_paths", "export_run", "trajectory_frame_rate", "pedpy_walkable_area",
           "pedpy_measurement_line", "pedpy_measurement_area", "fundamental_diagram_data"]

TXT_COLUMNS = ("id", "frame", "x/m", "y/m", "z/m", "heading/rad")
DEFAULT_FRAME_RATE_PER_S = 25.0


def require_pedpy():
    """The pedpy module; :class:`MissingDependencyError` with the install command when it is missing."""
    try:
        import pedpy
    except ImportError as exc:  # optional dependency
        raise MissingDependencyError("PedPy is not installed: pip install 'crowd_env[analysis]' (or pip install pedpy)") from exc
    return pedpy


def _check_frame_rate(frame_rate_per_s, what: str = "frame_rate_per_s") -> float:
    return check_number(what, frame_rate_per_s, error=TrajectoryFormatError, positive=True)


@dataclass(frozen=True, eq=False)
class Trajectories:
    """Long-format trajectories at a constant frame rate: row k is pedestrian ``id[k]`` at frame ``frame[k]``,
    time ``frame[k] / frame_rate_per_s``, position (``x_m[k]``, ``y_m[k]``), heading ``heading_rad[k]`` (NaN if
    unknown). Rows are sorted by (id, frame); (id, frame) pairs are unique. Arrays are read-only."""

    frame: np.ndarray
    id: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray
    heading_rad: np.ndarray
    frame_rate_per_s: float

    def __post_init__(self) -> None:
        fps = _check_frame_rate(self.frame_rate_per_s)
        frame = np.asarray(self.frame)
        ids = np.asarray(self.id)
        x = np.asarray(self.x_m, dtype=np.float64).ravel()
        y = np.asarray(self.y_m, dtype=np.float64).ravel()
        head = np.full(x.shape, np.nan) if self.heading_rad is None else np.asarray(self.heading_rad, dtype=np.float64)
        for name, arr in (("frame", frame), ("id", ids)):
            if arr.size and not np.issubdtype(arr.dtype, np.integer):
                if not (np.issubdtype(arr.dtype, np.floating) and np.all(np.isfinite(arr)) and np.all(arr == np.round(arr))):
                    raise TrajectoryFormatError(f"{name} must hold integers, got dtype {arr.dtype} with non-integer values")
        frame = frame.astype(np.int64).ravel()
        ids = ids.astype(np.int64).ravel()
        head = head.ravel()
        if not (frame.shape == ids.shape == x.shape == y.shape == head.shape):
            raise TrajectoryFormatError(f"frame, id, x_m, y_m and heading_rad must have equal lengths, got "
                                        f"{frame.size}, {ids.size}, {x.size}, {y.size}, {head.size}")
        if frame.size and frame.min() < 0:
            raise TrajectoryFormatError(f"frame numbers must be >= 0, got {int(frame.min())}")
        bad = np.flatnonzero(~(np.isfinite(x) & np.isfinite(y)))
        if bad.size:
            k = int(bad[0])
            raise TrajectoryFormatError(f"non-finite position ({x[k]}, {y[k]}) for id {int(ids[k])} at frame {int(frame[k])}")
        order = np.lexsort((frame, ids))
        frame, ids, x, y, head = frame[order], ids[order], x[order], y[order], head[order]
        dup = np.flatnonzero((ids[1:] == ids[:-1]) & (frame[1:] == frame[:-1]))
        if dup.size:
            k = int(dup[0])
            raise TrajectoryFormatError(f"pedestrian {int(ids[k])} appears twice in frame {int(frame[k])}")
        for name, arr in (("frame", frame), ("id", ids), ("x_m", x), ("y_m", y), ("heading_rad", head)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "frame_rate_per_s", fps)

    # -- derived -----------------------------------------------------------------------------------
    def __len__(self) -> int:
        return int(self.frame.size)

    @property
    def time_s(self) -> np.ndarray:
        """Time (s) of each row, ``frame / frame_rate_per_s`` (PedPy's convention)."""
        return self.frame / self.frame_rate_per_s

    @property
    def frame_interval_s(self) -> float:
        return 1.0 / self.frame_rate_per_s

    @property
    def n_pedestrians(self) -> int:
        return int(np.unique(self.id).size)

    @property
    def frame_time_s(self) -> np.ndarray:
        """Time (s) of frames 0..last, indexed by frame number (as the recorder's), for :mod:`.flow`."""
        n = int(self.frame.max()) + 1 if self.frame.size else 0
        return np.arange(n) / self.frame_rate_per_s

    # -- conversions -------------------------------------------------------------------------------
    @classmethod
    def from_recorder(cls, recorder: TrajectoryRecorder, frame_rate_per_s: float | None = None,
                      active_only: bool = True) -> "Trajectories":
        """From a :class:`TrajectoryRecorder` whose frames are evenly spaced in time.

        ``frame_rate_per_s`` defaults to the inverse of the recorded interval (give it to keep a round value;
        it is checked against the recorded times). Frame numbers are shifted so that ``frame / frame_rate``
        is the recorded time. Raises :class:`TrajectoryFormatError` for fewer than two frames or uneven
        spacing (PedPy needs a constant frame rate: record every k-th step, see :func:`steps_per_frame`).
        """
        times = recorder.frame_time_s
        if times.size < 2:
            raise TrajectoryFormatError(f"need at least two recorded frames to define a frame rate, got {times.size}")
        dt = np.diff(times)
        interval = float(np.median(dt)) if frame_rate_per_s is None else 1.0 / _check_frame_rate(frame_rate_per_s)
        if interval <= 0 or np.max(np.abs(dt - interval)) > 1e-6 * interval:
            raise TrajectoryFormatError(f"recorded frames are not evenly spaced in time (intervals from {dt.min():.6g} "
                                        f"to {dt.max():.6g} s): PedPy needs a constant frame rate; record every k-th step")
        offset = int(round(times[0] / interval))
        if abs(times[0] - offset * interval) > 1e-6 * interval:
            raise TrajectoryFormatError(f"the first recorded time {times[0]:.9g} s is not a multiple of the frame "
                                        f"interval {interval:.9g} s, so frame / frame rate cannot equal the time")
        a = recorder.to_arrays(active_only=active_only)
        fps = 1.0 / interval if frame_rate_per_s is None else float(frame_rate_per_s)
        return cls(a["frame"] + offset, a["id"], a["x"], a["y"], a["heading"], fps)

    def to_pedpy(self):
        """A ``pedpy.TrajectoryData`` (columns id, frame, x, y; coordinates in metres)."""
        import pandas as pd

        pedpy = require_pedpy()
        if not len(self):
            raise TrajectoryFormatError("no trajectory rows: PedPy cannot analyse an empty trajectory")
        data = pd.DataFrame({"id": self.id, "frame": self.frame, "x": self.x_m, "y": self.y_m})
        return pedpy.TrajectoryData(data=data, frame_rate=self.frame_rate_per_s)

    @classmethod
    def from_pedpy(cls, traj_data) -> "Trajectories":
        """From a ``pedpy.TrajectoryData`` (headings unknown: NaN)."""
        d = getattr(traj_data, "data", None)
        if d is None or not hasattr(traj_data, "frame_rate"):
            raise TrajectoryFormatError(f"expected a pedpy.TrajectoryData, got {type(traj_data).__name__}")
        missing = [c for c in ("id", "frame", "x", "y") if c not in d.columns]
        if missing:
            raise TrajectoryFormatError(f"TrajectoryData lacks column(s) {missing}")
        return cls(d["frame"].to_numpy(), d["id"].to_numpy(), d["x"].to_numpy(), d["y"].to_numpy(),
                   np.full(len(d), np.nan), traj_data.frame_rate)

    # -- text files (PedPy's load_trajectory_from_txt format) --------------------------------------
    def write_txt(self, path, comments=()) -> Path:
        """Write ``path`` in the format of ``pedpy.load_trajectory_from_txt`` (atomically: tmp file + rename).

        Header: free ``comments`` (one line each, without the word 'framerate', whose line PedPy's header
        parser takes for the frame rate), ``# framerate: <fps>`` and, last, the column line
        ``# id frame x/m y/m z/m heading/rad`` (marks metres for PedPy). Positions at 1 µm, z = 0.
        """
        path = Path(path)
        lines = []
        for c in comments:
            c = str(c)
            if "\n" in c or "framerate" in c.lower():
                raise TrajectoryFormatError(f"header comment {c!r} must be one line without the word 'framerate'")
            lines.append(f"# {c}")
        lines.append(f"# framerate: {self.frame_rate_per_s!r}")
        lines.append("# " + " ".join(TXT_COLUMNS))
        text = io.StringIO()
        text.write("\n".join(lines) + "\n")
        np.savetxt(text, np.column_stack([self.id, self.frame, self.x_m, self.y_m, np.zeros(len(self)),
                                          self.heading_rad]),
                   fmt=("%d", "%d", "%.6f", "%.6f", "%.1f", "%.6f"))
        write_atomic(path, text.getvalue())
        return path

    @classmethod
    def read_txt(cls, path, default_frame_rate_per_s: float | None = None, unit: str | None = None) -> "Trajectories":
        """Read a PedPy text trajectory (ours or PeTrack-style: id frame x y z [...]), without PedPy; a name
        ending in ``.gz`` is read gzipped.

        The frame rate comes from the first header line containing 'framerate' (as in PedPy), else from
        ``default_frame_rate_per_s``; coordinates are metres unless the header says 'x/cm' or 'in cm', or
        ``unit`` (``"m"`` or ``"cm"``) says otherwise (a file without a header: PeTrack's exports in cm).
        A sixth column is read as the heading (rad). Raises ``FileNotFoundError`` or
        :class:`TrajectoryFormatError` naming the problem.
        """
        path = Path(path)
        if unit not in (None, "m", "cm"):
            raise TrajectoryFormatError(f"unit must be 'm' or 'cm' (or None: from the header), got {unit!r}")
        if not path.exists():
            raise MissingFileError(f"trajectory file {path} does not exist")
        if not path.is_file():
            raise TrajectoryFormatError(f"trajectory path {path} is not a file")
        try:
            raw = path.read_bytes()
            text = (gzip.decompress(raw) if path.name.endswith(".gz") else raw).decode("utf-8-sig")
        except (UnicodeDecodeError, OSError, EOFError):
            raise TrajectoryFormatError(f"{path} is not a text trajectory file (not UTF-8 text, or a broken .gz)") from None
        fps, centimetres = None, False
        for line in text.splitlines():
            if not line.startswith("#"):
                break
            low = line.lower()
            if "framerate" in low and fps is None:
                for word in line.split():
                    try:
                        fps = float(word)
                        break
                    except ValueError:
                        continue
                if fps is None:
                    raise TrajectoryFormatError(f"{path}: the framerate line {line!r} holds no number")
            if "x/cm" in low or "in cm" in low:
                centimetres = True
            if "x/m" in low or "in m" in low:
                centimetres = False
        if fps is None:
            if default_frame_rate_per_s is None:
                raise TrajectoryFormatError(f"{path}: no frame rate in the header (expected a line like "
                                            f"'#framerate: 25'); pass default_frame_rate_per_s")
            fps = default_frame_rate_per_s
        fps = _check_frame_rate(fps, f"{path}: frame rate")
        rows = [ln.split() for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
        if not rows:
            raise TrajectoryFormatError(f"{path} contains no trajectory rows (expected columns id frame x y z)")
        widths = {len(r) for r in rows}
        if min(widths) < 4:
            k = next(i for i, r in enumerate(rows) if len(r) < 4)
            raise TrajectoryFormatError(f"{path} is not a trajectory file: data row {k + 1} has {len(rows[k])} "
                                        f"whitespace-separated column(s), expected at least id frame x y (z)")
        ncol = 6 if min(widths) >= 6 else 4
        try:
            data = np.array([r[:ncol] for r in rows], dtype=np.float64)
        except ValueError as exc:
            raise TrajectoryFormatError(f"{path} is not a trajectory file: non-numeric data ({exc})") from None
        scale = 0.01 if (centimetres if unit is None else unit == "cm") else 1.0
        head = data[:, 5] if ncol == 6 else None
        return cls(data[:, 1], data[:, 0], data[:, 2] * scale, data[:, 3] * scale, head, fps)


def trajectory_frame_rate(path) -> float | None:
    """The frame rate in a trajectory file's header, or None when the file is missing or has none."""
    path = Path(path)
    if not path.is_file():
        return None
    with open(path, encoding="utf-8-sig", errors="replace") as fh:
        for line in fh:
            if not line.startswith("#"):
                return None
            if "framerate" in line.lower():
                for word in line.split():
                    try:
                        return float(word)
                    except ValueError:
                        continue
    return None


# -- frame rate ------------------------------------------------------------------------------------
def steps_per_frame(frame_rate_per_s: float, dt_s: float) -> int:
    """Number of simulation steps h per frame: 1 / (fps · h), which must be a positive integer."""
    fps = _check_frame_rate(frame_rate_per_s)
    k = 1.0 / (fps * float(dt_s))
    every = int(round(k))
    if every < 1 or abs(k - every) > 1e-6 * k:
        options = ", ".join(f"{1.0 / (m * dt_s):g}" for m in (1, 2, 4, 5, 10))
        raise TrajectoryFormatError(f"frame rate {fps:g}/s is not 1/(k h) for an integer k with the step h = {dt_s:g} s "
                                    f"(e.g. {options})")
    return every


# -- geometry --------------------------------------------------------------------------------------
def _wkt(geom) -> str:
    return shapely.to_wkt(geom, rounding_precision=-1)


def write_geometry(path, geometry, metadata: dict | None = None) -> list:
    """Write ``path`` (JSON) with the walkable area, exits, measurement lines and areas, and beside it
    ``<stem>.wkt`` holding the walkable area alone (``pedpy.WalkableArea(text)`` reads it).

    The walkable area written is the geometry's navigable area (walkable area united with the exits),
    where every recorded position lies. JSON keys: ``walkable_area_wkt``, ``exits_wkt`` (list),
    ``measurement_lines`` (name -> [[x0, y0], [x1, y1]] in m), ``measurement_areas_wkt`` (name -> WKT),
    ``name``, ``metadata``, for a periodic geometry ``period_x_m``, and for lines given a direction
    ``measurement_line_directions`` (name -> {"direction": [x, y], "against_walkers": bool}). Returns the paths
    written.
    """
    path = Path(path)
    record = {
        "name": geometry.name,
        "walkable_area_wkt": _wkt(geometry.navigable_area),
        "exits_wkt": [_wkt(e) for e in geometry.exits],
        "measurement_lines": {k: np.asarray(v).tolist() for k, v in geometry.measurement_lines.items()},
        "measurement_areas_wkt": {k: _wkt(v) for k, v in geometry.measurement_areas.items()},
        "metadata": dict(metadata or {}),
    }
    if getattr(geometry, "period_x_m", 0.0):
        record["period_x_m"] = float(geometry.period_x_m)
    if geometry.measurement_line_directions:
        record["measurement_line_directions"] = {
            k: {"direction": d.tolist(), "against_walkers": k in geometry.lines_against_walkers}
            for k, d in geometry.measurement_line_directions.items()}
    wkt_path = geometry_paths(path)[1]
    for p, text in ((path, json.dumps(record, indent=1)), (wkt_path, record["walkable_area_wkt"] + "\n")):
        write_atomic(p, text)
    return [path, wkt_path]


def geometry_paths(path) -> tuple:
    """(JSON path, WKT path) of a geometry written by :func:`write_geometry` to ``path``."""
    path = Path(path)
    stem = path.name[:-len(".json")] if path.name.endswith(".json") else path.name
    return path, path.with_name(stem + ".wkt")


def read_geometry(path):
    """A :class:`~crowd_env.core.geometry.Geometry` from a file of :func:`write_geometry` (errors name the problem)."""
    from ..core.geometry import Geometry, GeometryError

    path = Path(path)
    if not path.is_file():
        raise MissingFileError(f"geometry file {path} does not exist")
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise TrajectoryFormatError(f"{path} is not a geometry JSON file ({exc})") from None
    if not isinstance(record, dict) or "walkable_area_wkt" not in record or "exits_wkt" not in record:
        raise TrajectoryFormatError(f"{path} is not a crowd_env geometry file: keys 'walkable_area_wkt' and "
                                    f"'exits_wkt' are required")
    lines = dict(record.get("measurement_lines") or {})
    directions = record.get("measurement_line_directions") or {}
    try:
        if not isinstance(directions, dict) or not all(isinstance(d, dict) for d in directions.values()):
            raise GeometryError(f"measurement_line_directions must map line names to dicts, got {directions!r}")
        lines.update({k: {"ends": lines.get(k), **d} for k, d in directions.items()})
        return Geometry.from_wkt(record["walkable_area_wkt"], list(record["exits_wkt"]),
                                 measurement_lines=lines,
                                 measurement_areas=record.get("measurement_areas_wkt") or {},
                                 name=record.get("name", "geometry"), period_x_m=record.get("period_x_m", 0.0))
    except GeometryError as exc:
        raise TrajectoryFormatError(f"{path}: {exc}") from exc


def export_run(stem, trajectories: Trajectories, geometry, comments=(), metadata: dict | None = None) -> list:
    """Write ``<stem>.txt`` (trajectories), ``<stem>.geometry.json`` and ``<stem>.geometry.wkt``; returns the paths.

    The geometry is written first and the trajectory last, so an existing ``.txt`` implies complete files.
    """
    stem = Path(stem)
    paths = write_geometry(stem.with_name(stem.name + ".geometry.json"), geometry, metadata)
    paths.insert(0, trajectories.write_txt(stem.with_name(stem.name + ".txt"), comments))
    return paths


def pedpy_walkable_area(geometry):
    """``pedpy.WalkableArea`` of a Geometry's navigable area (walkable area with the exits)."""
    return require_pedpy().WalkableArea(geometry.navigable_area)


def pedpy_measurement_line(geometry, name: str = "bottleneck"):
    """``pedpy.MeasurementLine`` of the geometry's measurement line ``name``."""
    if name not in geometry.measurement_lines:
        raise NotFoundError(f"geometry has no measurement line {name!r}; it has {sorted(geometry.measurement_lines)}")
    return require_pedpy().MeasurementLine(np.asarray(geometry.measurement_lines[name]).tolist())


def pedpy_measurement_area(geometry, name: str):
    """``pedpy.MeasurementArea`` of the geometry's (convex) measurement area ``name``."""
    if name not in geometry.measurement_areas:
        raise NotFoundError(f"geometry has no measurement area {name!r}; it has {sorted(geometry.measurement_areas)}")
    return require_pedpy().MeasurementArea(geometry.measurement_areas[name])


# -- PedPy measures --------------------------------------------------------------------------------
def fundamental_diagram_data(traj_data, measurement_area, speed_window_s: float = 0.4) -> dict:
    """Per-frame classic density, mean speed and specific flow ρ·v in ``measurement_area``, by PedPy.

    ``traj_data``: ``pedpy.TrajectoryData`` or :class:`Trajectories`; ``measurement_area``:
    ``pedpy.MeasurementArea``. Individual speeds (``compute_individual_speed``) use a centred window of
    ``speed_window_s`` (one-sided at trajectory ends); densities come from ``compute_classic_density``
    and mean speeds from ``compute_mean_speed_per_frame``. Frames with nobody in the area are dropped.
    Returns arrays ``frame``, ``time_s``, ``density_per_m2``, ``speed_m_s``, ``specific_flow_per_m_s``.
    """
    pedpy = require_pedpy()
    if isinstance(traj_data, Trajectories):
        traj_data = traj_data.to_pedpy()
    check_number("speed_window_s", speed_window_s, error=InputError, positive=True)
    frame_step = max(1, int(round(0.5 * speed_window_s * traj_data.frame_rate)))
    speed = pedpy.compute_individual_speed(traj_data=traj_data, frame_step=frame_step,
                                           speed_calculation=pedpy.SpeedCalculation.BORDER_SINGLE_SIDED)
    density = pedpy.compute_classic_density(traj_data=traj_data, measurement_area=measurement_area)
    mean_speed = pedpy.compute_mean_speed_per_frame(traj_data=traj_data, individual_speed=speed,
                                                    measurement_area=measurement_area)
    merged = density.merge(mean_speed, on="frame")
    merged = merged[merged["density"] > 0]
    rho = merged["density"].to_numpy(dtype=np.float64)
    v = merged["speed"].to_numpy(dtype=np.float64)
    frame = merged["frame"].to_numpy(dtype=np.int64)
    return {"frame": frame, "time_s": frame / traj_data.frame_rate, "density_per_m2": rho, "speed_m_s": v,
            "specific_flow_per_m_s": rho * v}
