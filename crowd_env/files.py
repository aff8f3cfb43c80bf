"""Atomic file writes: every table, record, figure and array file of crowd_env goes to a temporary name, is
fsync'ed and renamed, so a killed process never leaves a half-written file under the final name; logs that grow
during a run are appended a whole line at a time (``tests/test_files.py`` scans the package for writes that
bypass this module).

A leaf module (numpy, the standard library and crowd_env.errors only) that every layer may use.
"""
from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path

import numpy as np

from crowd_env.errors import InputError

__all__ = ["write_atomic", "write_json_atomic", "write_csv_atomic", "write_npz_atomic", "save_figure_atomic", "read_json_lines",
           "copy_atomic", "append_json_line"]


def write_atomic(path: Path, text: str | bytes) -> None:
    """Write ``text`` (or bytes) to ``path`` through a temporary file, fsync'ed and renamed: a killed
    process never leaves a half-written file under the final name."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    with open(tmp, "wb") if isinstance(text, bytes) else open(tmp, "w", encoding="utf-8") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())
    tmp.replace(path)


def write_json_atomic(path, value, **dumps_options) -> None:
    """``value`` as JSON at ``path``, its folder made if needed, written atomically (:func:`write_atomic`);
    ``dumps_options`` go to :func:`json.dumps` (default ``indent=1``; ``indent=None``: one line)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, json.dumps(value, **{"indent": 1, **dumps_options}))


def write_csv_atomic(path, fieldnames: list, rows, **options) -> None:
    """``rows`` as CSV at ``path`` under ``fieldnames`` (``options`` go to :class:`csv.DictWriter`), written
    atomically (:func:`write_atomic`): a killed run never leaves half a table. A row is a dict, or a sequence of
    one value per field in their order (another length raises :class:`~crowd_env.errors.InputError` naming the
    row, before anything is written)."""
    buffer = io.StringIO(newline="")
    w = csv.DictWriter(buffer, fieldnames=fieldnames, **options)
    w.writeheader()
    for k, row in enumerate(rows):
        if not isinstance(row, dict):
            row = list(row)
            if len(row) != len(fieldnames):
                raise InputError(f"row {k} of {path} has {len(row)} values for {len(fieldnames)} columns")
            row = dict(zip(fieldnames, row))
        w.writerow(row)
    write_atomic(path, buffer.getvalue())


def write_npz_atomic(path, meta: dict, **arrays) -> None:
    """``arrays`` and ``meta`` (as a JSON string under the key ``meta``) in a compressed ``.npz`` at ``path``,
    its folder made if needed, written atomically (:func:`write_atomic`)."""
    buffer = io.BytesIO()
    np.savez_compressed(buffer, meta=np.array(json.dumps(meta)), **arrays)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, buffer.getvalue())


def save_figure_atomic(fig, path, **options) -> str:
    """``fig.savefig(path, **options)`` (a matplotlib figure; the format from the suffix), written atomically
    (:func:`write_atomic`), its folder made if needed; returns ``path``."""
    target = Path(path)
    buffer = io.BytesIO()
    fig.savefig(buffer, format=target.suffix.lstrip(".") or "png", **options)
    target.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(target, buffer.getvalue())
    return path


def copy_atomic(source, destination) -> str:
    """Copy the file ``source`` to ``destination`` (a file path) through :func:`write_atomic`; returns
    ``destination``."""
    write_atomic(Path(destination), Path(source).read_bytes())
    return destination


def append_json_line(path, value) -> None:
    """Append ``value`` as one JSON line to ``path`` (made with its folder if needed) in one write, fsync'ed: the
    log files that grow during a run (failed runs, evaluated points). A kill can cut only the last line, which
    their readers skip."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a", encoding="utf-8") as fh:
        fh.write(json.dumps(value) + "\n")
        fh.flush()
        os.fsync(fh.fileno())


def read_json_lines(path) -> list:
    """The values of the JSON lines of ``path`` (:func:`append_json_line`'s logs), in order; [] when there is no
    file. A line that is not JSON (the last one, cut by a kill) is skipped."""
    path = Path(path)
    if not path.exists():
        return []
    out = []
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return out
