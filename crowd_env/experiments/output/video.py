"""Videos (MP4 or GIF) of a rollout of any policy on any scenario, or of a saved trajectory file.

Both sources draw their frames with the one drawing function of the environment's renderer,
:meth:`crowd_env.envs.rendering.CrowdRenderer.draw_frame`: learned (controlled) pedestrians blue,
background ones grey, each pedestrian's heading a line from its centre to its rim, and contact
percussions as lines between touching pedestrians (or a pedestrian and the wall), wider and redder as the
normal percussion summed over the simulator steps since the previous frame grows.

- :func:`record_rollout`: one episode of the evaluation harness
  (:func:`crowd_env.experiments.running.evaluation.run_episode`, the same policies, scenarios, seeds and metrics
  as ``crowd-evaluate``) with a :class:`RolloutVideo` reading the environment after every step;
  percussions come from the simulator's sub-steps (``env.substep_hooks``,
  :class:`crowd_env.envs.rendering.ContactPercussions`).
- :func:`record_trajectory_file`: a trajectory file in PedPy's text format
  (:meth:`crowd_env.analysis.trajectories.Trajectories.read_txt`, e.g. written by
  :func:`crowd_env.analysis.trajectories.export_run`) with its geometry, the JSON file of
  :func:`crowd_env.analysis.trajectories.write_geometry` (by default ``<stem>.geometry.json`` beside
  ``<stem>.txt``, as ``export_run`` names it). These files hold positions and headings only: radii are
  one given value, nobody is learned unless named, and there are no percussions to draw.
- :func:`per_policy`: the recorders of ``crowd-evaluate --video`` (the first episode of each policy).

Time: a frame every ``every`` environment steps (rollout) or trajectory-file frames, i.e. every
``every × step`` simulated seconds. Without ``fps`` the video plays in real time,
``fps = 1 / (every × step)``: one second of video is one second of simulated time. Without ``every``
it is ``1 / (fps × step)`` (which must then be a whole number, so that the video is in real time); with
neither, the smallest stride whose frames are at least 1/25 s apart. With both, the video plays
``fps × every × step`` times faster than real time (:attr:`VideoInfo.speed`). Frames are taken at the
start (t = 0 of the episode, the first frame of the file) and then at every stride; an episode's last
steps after the last multiple of the stride make no frame.

Formats: the file name's extension picks it, ``.mp4`` (H.264 through imageio's ffmpeg plugin,
``imageio-ffmpeg``; frame sizes are multiples of 16 pixels) or ``.gif`` (pillow; frame durations are whole
hundredths of a second, so ``fps`` must divide 100, and the frames are held in memory until the file
is written: prefer MP4 for long episodes). Both need ``pip install 'crowd_env[video]'``. The video is
written to a temporary file beside the target and renamed at the end, so a failed run leaves no partial
video.
"""
from __future__ import annotations

import importlib
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...analysis.trajectories import Trajectories, geometry_paths, read_geometry
from ...core.checks import check_integer, check_number
from ...core.params import PedestrianDefaults
from ...envs.rendering import ContactPercussions, CrowdRenderer
from crowd_env.errors import InputError, MissingDependencyError, MissingFileError, NotFoundError, PolicyError
from ..running.evaluation import ScenarioSpec, import_object, resolve_policy, run_episode

__all__ = ["VIDEO_FORMATS", "MAX_DEFAULT_FPS", "DEFAULT_QUALITY", "VideoInfo", "VideoWriter", "RolloutVideo", "check_video_path",
           "frame_stride", "policy_from_spec", "record_rollout", "record_trajectory_file", "per_policy",
           "per_policy_path", "geometry_path_for"]

VIDEO_FORMATS = {".mp4": "MP4 (H.264, imageio's ffmpeg plugin)", ".gif": "GIF (pillow)"}
MAX_DEFAULT_FPS = 25.0  # without fps or every: the smallest stride with frames at least 1/25 s apart
DEFAULT_QUALITY = 7.0  # MP4: imageio's quality, 0 (smallest file) to 10 (best)
_EXTRA = "pip install 'crowd_env[video]'"


@dataclass(frozen=True)
class VideoInfo:
    """What was written: ``path``, ``n_frames``, ``fps`` (video frames per second), ``every`` (steps or
    file frames per video frame), ``frame_interval_s`` (simulated seconds between frames), ``speed``
    (simulated seconds per second of video; 1 = real time) and ``size`` (width, height) in pixels."""

    path: Path
    n_frames: int
    fps: float
    every: int
    frame_interval_s: float
    speed: float
    size: tuple


def check_video_path(path) -> Path:
    """``path`` as a Path after checking that its extension is one of :data:`VIDEO_FORMATS` (``.mp4``,
    ``.gif``; :class:`~crowd_env.errors.InputError` otherwise), that its folder exists
    (:class:`~crowd_env.errors.MissingFileError`) and that the writer it needs is installed
    (:class:`~crowd_env.errors.MissingDependencyError` naming the ``video`` extra)."""
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in VIDEO_FORMATS:
        raise InputError(f"video file {str(path)!r}: unknown extension {ext or '(none)'!r}; the name must end in "
                         f"{' or '.join(VIDEO_FORMATS)} ({', '.join(VIDEO_FORMATS.values())})")
    if not path.parent.is_dir():
        raise MissingFileError(f"video file {path}: folder {path.parent} does not exist")
    try:
        importlib.import_module("imageio")
    except ImportError as exc:
        raise MissingDependencyError(f"writing {path} needs imageio, which is not installed: {_EXTRA}") from exc
    if ext == ".mp4":
        try:
            import imageio_ffmpeg

            imageio_ffmpeg.get_ffmpeg_exe()
        except (ImportError, RuntimeError) as exc:
            raise MissingDependencyError(f"writing {path} (MP4) needs imageio-ffmpeg and its ffmpeg binary, which are "
                                         f"not installed ({exc}): {_EXTRA}, or name the video .gif") from exc
    return path


def _check_fps(fps) -> float:
    """Video frames per second: a positive finite number."""
    return check_number("fps", fps, error=InputError, positive=True)


def _check_quality(quality) -> float:
    if isinstance(quality, bool) or not isinstance(quality, (int, float)) or not 0 <= quality <= 10:
        raise InputError(f"quality must be a number from 0 (smallest file) to 10 (best), got {quality!r}")
    return float(quality)


def _check_every(every) -> int:
    return check_integer("every (the frame stride)", every, error=InputError, minimum=1)


def _check_gif_fps(fps: float) -> None:
    cs = 100.0 / fps
    if abs(cs - round(cs)) > 1e-6 * cs or round(cs) < 1:
        ok = ", ".join(f"{100 / k:g}" for k in (2, 4, 5, 10, 20, 25) if 100 / k <= 2 * fps or k == 25)
        raise InputError(f"a GIF frame lasts a whole number of hundredths of a second, so fps {fps:g} cannot be "
                         f"written (1/fps = {1 / fps:.6g} s): use an fps that divides 100 (e.g. {ok}), or an .mp4")


def frame_stride(step_s: float, fps=None, every=None, *, gif: bool = False) -> tuple:
    """``(every, fps)`` for frames of a source with one step (environment step or file frame) per ``step_s``
    simulated seconds; see the module docstring for the rules. Raises
    :class:`~crowd_env.errors.InputError` for ``fps`` <= 0, ``every`` < 1, an ``fps`` alone that is not
    1/(k × step) for a whole k, and (``gif``) an fps that does not divide 100."""
    step_s = check_number("step_s", step_s, error=InputError, positive=True)
    fps = None if fps is None else _check_fps(fps)
    every = None if every is None else _check_every(every)
    if every is None and fps is None:
        candidates = range(max(1, math.ceil(1.0 / (MAX_DEFAULT_FPS * step_s) - 1e-9)), 10_001)
        for k in candidates:
            rate = 1.0 / (k * step_s)
            if not gif or abs(100.0 / rate - round(100.0 / rate)) <= 1e-6 * 100.0 / rate:
                return k, rate
        raise InputError(f"no frame stride of steps of {step_s:g} s gives GIF frames of whole hundredths of a "
                         f"second: give fps and every, or write an .mp4")
    if fps is None:
        fps = 1.0 / (every * step_s)
    elif every is None:
        k = 1.0 / (fps * step_s)
        every = int(round(k))
        if every < 1 or abs(k - every) > 1e-6 * k:
            rates = ", ".join(f"{1.0 / (m * step_s):g}" for m in (1, 2, 4, 5, 10))
            raise InputError(f"fps {fps:g} does not follow simulated time: a frame every 1/{fps:g} s is "
                             f"{k:.6g} steps of {step_s:g} s, not a whole number; use an fps of 1/(k × {step_s:g} s) "
                             f"(e.g. {rates}), or give every (frames every that many steps, played at fps)")
    if gif:
        _check_gif_fps(fps)
    return every, fps


class VideoWriter:
    """Streams RGB frames (H, W, 3) uint8 into ``path`` (``.mp4`` or ``.gif``) at ``fps``; a context manager.
    The frames go to a temporary file beside ``path``, renamed to ``path`` by :meth:`close`;
    :meth:`close` with ``keep=False`` (or an exception inside the ``with`` block) removes it instead."""

    def __init__(self, path, fps: float, quality: float = DEFAULT_QUALITY):
        self.path = check_video_path(path)
        self.fps = _check_fps(fps)
        self.quality = _check_quality(quality)
        self.gif = self.path.suffix.lower() == ".gif"
        if self.gif:
            _check_gif_fps(self.fps)
        self.n_frames = 0
        self.size = None
        self._tmp = self.path.with_name(f".{self.path.stem}.partial{self.path.suffix}")
        self._writer = None

    def _open(self):
        if self.gif:
            import imageio.v3 as iio

            return iio.imopen(self._tmp, "w", plugin="pillow", extension=".gif")
        import imageio.v2 as iio2

        return iio2.get_writer(self._tmp, format="FFMPEG", mode="I", fps=self.fps, codec="libx264",
                               pixelformat="yuv420p", macro_block_size=16, quality=self.quality,
                               ffmpeg_log_level="error")

    def append(self, frame) -> None:
        frame = np.asarray(frame)
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
            raise InputError(f"a video frame must be an (H, W, 3) uint8 RGB image, got {frame.dtype} {frame.shape}")
        size = (frame.shape[1], frame.shape[0])
        if self.size is None:
            self.size = size
            self._writer = self._open()
        elif size != self.size:
            raise InputError(f"frame {self.n_frames} is {size[0]}x{size[1]} pixels, the video's frames "
                             f"{self.size[0]}x{self.size[1]}")
        if self.gif:
            self._writer.write(frame, duration=1000.0 / self.fps, loop=0, is_batch=False)
        else:
            self._writer.append_data(frame)
        self.n_frames += 1

    def close(self, keep: bool = True) -> None:
        writer, self._writer = self._writer, None
        if writer is not None:
            writer.close()
        if keep and self.n_frames:
            self._tmp.replace(self.path)
        else:
            self._tmp.unlink(missing_ok=True)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        self.close(keep=exc_type is None)
        return False


def _title(label: str, time_s: float, active, controlled, pmax: float | None) -> str:
    n_on = int(np.count_nonzero(active))
    n_learned = int(np.count_nonzero(active & controlled))
    text = f"{label}   t = {time_s:.2f} s   {n_on} on floor, {n_learned} learned"
    if pmax is not None:
        text += f"   max P_n {pmax:.1f} kg m/s"
    return text.strip()


class RolloutVideo:
    """Recorder of one episode of :func:`crowd_env.experiments.running.evaluation.run_episode` (its ``video``
    argument): a frame at the reset and then every ``every`` environment steps, with the percussions of
    the simulator steps in between; see the module docstring for ``fps`` and ``every``. After the
    episode :attr:`info` is the :class:`VideoInfo` of the file written. ``label`` starts each frame's title
    (default: nothing)."""

    def __init__(self, path, *, fps=None, every=None, label: str = "", percussion_scale_kg_m_s: float = 20.0,
                 width_in: float = 8.0, dpi: int = 80, quality: float = DEFAULT_QUALITY):
        self.path = check_video_path(path)
        self.quality = _check_quality(quality)
        self.fps = None if fps is None else _check_fps(fps)
        self.every = None if every is None else _check_every(every)
        self.label = str(label)
        self.percussion_scale_kg_m_s = percussion_scale_kg_m_s
        self.width_in, self.dpi = width_in, dpi
        self.info = None

    def begin(self, env) -> None:
        self._every, fps = frame_stride(env.dt_s, self.fps, self.every, gif=self.path.suffix.lower() == ".gif")
        self._step_s = env.dt_s
        self._controlled = env.controlled_mask
        self._renderer = CrowdRenderer(env.geometry, self._controlled, "rgb_array", width_in=self.width_in,
                                       dpi=self.dpi, pixel_multiple=16,
                                       percussion_scale_kg_m_s=self.percussion_scale_kg_m_s,
                                       body_depth_m=env.sim.physics.body_depth_m)
        self._writer = VideoWriter(self.path, fps, self.quality)
        self._contacts = ContactPercussions()
        env.substep_hooks.append(self._contacts)
        self._steps = 0
        self._frame(env)

    def after_step(self, env) -> None:
        self._steps += 1
        if self._steps % self._every == 0:
            self._frame(env)

    def _frame(self, env) -> None:
        st = env.sim.state
        contacts = self._contacts.take()
        pmax = float(contacts[3].max()) if contacts[3].size else 0.0
        title = _title(self.label, env.sim.time_s, st.active, self._controlled, pmax)
        self._writer.append(self._renderer.draw_frame(st.position_m, st.radius_m, st.heading_rad, st.active,
                                                      contacts=contacts, title=title))

    def end(self, env, completed: bool = True) -> None:
        if self._contacts in env.substep_hooks:
            env.substep_hooks.remove(self._contacts)
        self._renderer.close()
        self._writer.close(keep=completed)
        w = self._writer
        interval = self._every * self._step_s
        self.info = VideoInfo(self.path, w.n_frames, w.fps, self._every, interval, w.fps * interval, w.size)


def policy_from_spec(spec, resolver: str | None = None, name: str | None = None):
    """A policy from a spec as ``crowd-evaluate`` reads it: an import path ``module:attribute``
    (:func:`crowd_env.experiments.running.evaluation.resolve_policy`), a policy object, or a name or saved model
    given to the resolver function the import path ``resolver`` names (e.g.
    ``"baselines.reference_policies:as_policy"``). Any failure is a :class:`~crowd_env.errors.PolicyError`
    naming the spec."""
    try:
        if not isinstance(spec, str) or ":" in spec or resolver is None:
            return resolve_policy(spec, name=name)
        try:
            resolve = import_object(resolver)
        except ImportError as exc:
            raise PolicyError(f"policy resolver {resolver!r} cannot be imported ({exc})") from exc
        return resolve_policy(spec, name=name, resolve=resolve)
    except PolicyError:
        raise
    except (ImportError, ValueError, TypeError, KeyError) as exc:
        message = str(exc) if repr(spec) in str(exc) else f"unknown policy {spec!r}: {exc}"
        raise PolicyError(message) from exc


def record_rollout(policy, path, scenario="seyfried_bottleneck", seed: int = 0, *, scenario_options=None,
                   env_options: dict | None = None, max_time_s: float = 30.0, fps=None, every=None,
                   resolver: str | None = None, line: str | None = None, percussion_scale_kg_m_s: float = 20.0,
                   label: str | None = None, quality: float = DEFAULT_QUALITY) -> tuple:
    """Write a video of one episode of ``policy`` on ``scenario`` (a registered name with
    ``scenario_options``, or a :class:`~crowd_env.experiments.running.evaluation.ScenarioSpec`) with ``seed``, at
    most ``max_time_s`` simulated seconds, to ``path`` (``.mp4`` or ``.gif``). ``policy``: a policy object
    or a spec (:func:`policy_from_spec` with ``resolver``); ``env_options`` go to the environment as in
    :func:`~crowd_env.experiments.running.evaluation.run_episode` (``controlled`` defaults to ``"all"``).
    ``quality``: the MP4's, 0 (smallest file) to 10 (best; default 7). Returns ``(EpisodeMetrics, VideoInfo)``.
    The path, fps, stride and quality are checked before the episode runs."""
    path = check_video_path(path)
    if fps is not None:
        fps = _check_fps(fps)
    if every is not None:
        every = _check_every(every)
    check_number("max_time_s", max_time_s, error=InputError, positive=True)
    pol = policy_from_spec(policy, resolver)
    spec = scenario if isinstance(scenario, ScenarioSpec) else ScenarioSpec(scenario, scenario_options)
    name = getattr(pol, "name", type(pol).__name__)
    if label is None:
        label = f"{name}, {spec.scenario if isinstance(spec.scenario, str) else spec.label}, seed {seed}"
    video = RolloutVideo(path, fps=fps, every=every, label=label, percussion_scale_kg_m_s=percussion_scale_kg_m_s,
                         quality=quality)
    metrics = run_episode(pol, spec, seed, env_options=env_options, max_time_s=max_time_s, line=line, video=video)
    return metrics, video.info


def per_policy_path(path, label: str) -> Path:
    """``<stem>-<label><ext>``: the file of policy ``label`` for ``crowd-evaluate --video <stem><ext>``
    (characters other than letters, digits, ``.``, ``_`` and ``-`` in the label become ``_``)."""
    path = Path(path)
    safe = re.sub(r"[^A-Za-z0-9._-]+", "_", str(label)).strip("_") or "policy"
    return path.with_name(f"{path.stem}-{safe}{path.suffix}")


def per_policy(path, *, fps=None, every=None, percussion_scale_kg_m_s: float = 20.0, written: list | None = None):
    """The ``video`` argument of :func:`crowd_env.experiments.running.evaluation.evaluate`: for each policy label a
    :class:`RolloutVideo` writing :func:`per_policy_path` ``(path, label)``, so that the first episode of
    each policy (first scenario, first seed) is recorded. The recorders are appended to ``written`` when
    given (their :attr:`RolloutVideo.info` says what each wrote). ``path``, ``fps`` and ``every`` are
    checked at once."""
    check_video_path(path)
    fps = None if fps is None else _check_fps(fps)
    every = None if every is None else _check_every(every)

    def make(label: str) -> RolloutVideo:
        rec = RolloutVideo(per_policy_path(path, label), fps=fps, every=every, label=str(label),
                           percussion_scale_kg_m_s=percussion_scale_kg_m_s)
        if written is not None:
            written.append(rec)
        return rec

    return make


def geometry_path_for(trajectory_path) -> Path:
    """The geometry file :func:`crowd_env.analysis.trajectories.export_run` writes beside a trajectory file:
    ``<stem>.geometry.json`` for ``<stem>.txt``."""
    path = Path(trajectory_path)
    stem = path.name[:-len(".txt")] if path.name.endswith(".txt") else path.name
    return geometry_paths(path.with_name(stem + ".geometry.json"))[0]


def record_trajectory_file(trajectory_path, path, *, geometry=None, fps=None, every=None, max_time_s=None,
                           radius_m: float | None = None, learned_ids=(), label: str | None = None) -> VideoInfo:
    """Write a video of the trajectory file ``trajectory_path`` (PedPy text format,
    :meth:`~crowd_env.analysis.trajectories.Trajectories.read_txt`) to ``path`` (``.mp4`` or ``.gif``).

    ``geometry``: a :class:`~crowd_env.core.geometry.Geometry`, or the path of its JSON file
    (:func:`~crowd_env.analysis.trajectories.write_geometry`); by default :func:`geometry_path_for` the
    trajectory file (trajectory files hold no geometry). ``radius_m``: every pedestrian's radius
    (default :class:`~crowd_env.core.params.PedestrianDefaults`' 0.23 m; files hold no radii).
    ``learned_ids``: pedestrian ids drawn as learned (blue), the others background (grey). Headings come
    from the file's sixth column (none drawn where it is missing or NaN); no percussions (files hold
    none). Frames: the file's first frame, then every ``every``-th file frame up to its last, or up to
    ``max_time_s`` simulated seconds after the first; time is PedPy's ``frame / frame rate``.
    Errors: :class:`~crowd_env.errors.MissingFileError` (no trajectory or geometry file),
    :class:`~crowd_env.errors.TrajectoryFormatError` (malformed file), :class:`~crowd_env.errors.NotFoundError`
    (a learned id that is not in the file), :class:`~crowd_env.errors.InputError` (bad values).
    """
    path = check_video_path(path)
    fps = None if fps is None else _check_fps(fps)
    every = None if every is None else _check_every(every)
    if max_time_s is not None:
        check_number("max_time_s", max_time_s, error=InputError, minimum=0.0, suffix=" or None")
    radius = PedestrianDefaults().radius_m if radius_m is None else radius_m
    check_number("radius_m", radius, error=InputError, positive=True)
    traj = Trajectories.read_txt(trajectory_path)
    if geometry is None:
        geometry = geometry_path_for(trajectory_path)
        if not geometry.is_file():
            raise MissingFileError(f"no geometry for {trajectory_path}: trajectory files hold no geometry, and "
                                   f"{geometry} (where export_run writes it) does not exist; give the geometry "
                                   f"JSON file (write_geometry) explicitly")
    if isinstance(geometry, (str, Path)):
        geometry = read_geometry(geometry)
    elif not (hasattr(geometry, "walls") and hasattr(geometry, "bounds")):
        raise InputError(f"geometry must be a Geometry or the path of its JSON file, got {type(geometry).__name__}")
    ids = np.unique(traj.id)
    learned = np.asarray(list(learned_ids), dtype=np.int64)
    unknown = np.setdiff1d(learned, ids)
    if unknown.size:
        raise NotFoundError(f"learned id(s) {unknown.tolist()[:10]} are not in {trajectory_path} (ids "
                            f"{int(ids.min())}..{int(ids.max())})")
    step_s = traj.frame_interval_s
    every, fps = frame_stride(step_s, fps, every, gif=path.suffix.lower() == ".gif")
    first, last = int(traj.frame.min()), int(traj.frame.max())
    if max_time_s is not None:
        last = min(last, first + int(math.floor(max_time_s * traj.frame_rate_per_s + 1e-9)))
    frames = np.arange(first, last + 1, every)
    order = np.argsort(traj.frame, kind="stable")
    sorted_frames = traj.frame[order]
    column = np.searchsorted(ids, traj.id)
    controlled = np.isin(ids, learned)
    renderer = CrowdRenderer(geometry, controlled, "rgb_array", pixel_multiple=16)
    n = ids.size
    name = Path(trajectory_path).name if label is None else label
    try:
        with VideoWriter(path, fps) as writer:
            for f in frames:
                lo, hi = np.searchsorted(sorted_frames, [f, f + 1])
                rows = order[lo:hi]
                pos = np.zeros((n, 2))
                heading = np.full(n, np.nan)
                active = np.zeros(n, dtype=bool)
                col = column[rows]
                pos[col, 0] = traj.x_m[rows]
                pos[col, 1] = traj.y_m[rows]
                heading[col] = traj.heading_rad[rows]
                active[col] = True
                title = _title(name, f / traj.frame_rate_per_s, active, controlled, None)
                writer.append(renderer.draw_frame(pos, radius, heading, active, title=title))
    finally:
        renderer.close()
    interval = every * step_s
    return VideoInfo(path, writer.n_frames, writer.fps, every, interval, writer.fps * interval, writer.size)
