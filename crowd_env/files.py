"""Atomic file writes: every table, record and array file of crowd_env goes to a temporary name, is fsync'ed
and renamed, so a killed process never leaves a half-written file under the final name.

A leaf module (numpy and the standard library only) that every layer may use.
"""
from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path

import numpy as np

__all__ = ["write_atomic", "write_json_atomic", "write_csv_atomic", "write_npz_atomic"]


def write_atomic(path: Path, text: str | bytes) -> None:
    """Write ``text`` (or bytes) to ``path`` through a temporary file, fsync'ed and renamed: a killed
    process never leaves a half-written file under the final name."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    with open(tmp, "wb" if isinstance(text, bytes) else "w") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())
    tmp.replace(path)


def write_json_atomic(path, value) -> None:
    """``value`` as JSON (indented) at ``path``, its folder made if needed, written atomically
    (:func:`write_atomic`)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, json.dumps(value, indent=1))


def write_csv_atomic(path, fieldnames: list, rows, **options) -> None:
    """``rows`` (dicts) as CSV at ``path`` under ``fieldnames`` (``options`` go to :class:`csv.DictWriter`), written
    atomically (:func:`write_atomic`): a killed run never leaves half a table."""
    buffer = io.StringIO(newline="")
    w = csv.DictWriter(buffer, fieldnames=fieldnames, **options)
    w.writeheader()
    w.writerows(rows)
    write_atomic(path, buffer.getvalue())


def write_npz_atomic(path, meta: dict, **arrays) -> None:
    """``arrays`` and ``meta`` (as a JSON string under the key ``meta``) in a compressed ``.npz`` at ``path``,
    its folder made if needed, written atomically (:func:`write_atomic`)."""
    buffer = io.BytesIO()
    np.savez_compressed(buffer, meta=np.array(json.dumps(meta)), **arrays)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, buffer.getvalue())
