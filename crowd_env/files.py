"""Atomic file writes: every table, record, figure and array file of crowd_env goes to a temporary name, is
fsync'ed and renamed, so a killed process never leaves a half-written file under the final name; logs that grow
during a run are appended a whole line at a time (``tests/test_files.py`` scans the package for writes that
bypass this module).

Signed files. A pickle runs code when it is read, so the pickles crowd_env keeps to resume a run (run and SB3 /
RLlib training checkpoints) carry an HMAC-SHA256 under this account's secret key (:func:`secret_path`, made with
the first signed file, readable by its owner only) and are read back only when it matches: a checkpoint that this
account's crowd_env did not write, e.g. one in a run folder someone else shared, is refused unread
(:class:`~crowd_env.errors.UntrustedFileError`). :func:`write_signed_atomic` / :func:`read_signed` keep the code in
the file itself; :func:`files_digest` / :func:`check_files_digest` sign files other libraries write (the digest
goes into the checkpoints' index).

A leaf module (numpy, the standard library and crowd_env.errors only) that every layer may use.
"""
from __future__ import annotations

import csv
import hashlib
import hmac
import io
import json
import os
import secrets
from pathlib import Path

import numpy as np

from crowd_env.errors import InputError, UntrustedFileError

__all__ = ["write_atomic", "write_json_atomic", "write_csv_atomic", "write_npz_atomic", "save_figure_atomic",
           "copy_atomic", "append_json_line", "read_json_lines", "SECRET_FILE_ENV", "secret_path", "write_signed_atomic", "read_signed",
           "files_digest", "check_files_digest"]

SECRET_FILE_ENV = "CROWD_ENV_SECRET_FILE"  # the signing key's path, when set (the test suite sets one of its own)
SECRET_BYTES = 32
SIGNED_HEADER = b"crowd_env signed file/1\n"


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


def secret_path() -> Path:
    """This account's signing key: ``$CROWD_ENV_SECRET_FILE`` when set, else ``crowd_env/secret.key`` under
    ``$XDG_DATA_HOME`` (default ``~/.local/share``). It never lives in a run folder, which may be shared."""
    if os.environ.get(SECRET_FILE_ENV):
        return Path(os.environ[SECRET_FILE_ENV])
    data = os.environ.get("XDG_DATA_HOME") or os.path.join(os.path.expanduser("~"), ".local", "share")
    return Path(data) / "crowd_env" / "secret.key"


def _secret(create: bool) -> bytes | None:
    """The key at :func:`secret_path` (None when there is none and not ``create``); a new one is 32 random bytes,
    mode 0600, linked into place so that processes starting together agree on one."""
    path = secret_path()
    if not path.exists() and create:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{secrets.token_hex(8)}.tmp")
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "wb") as fh:
            fh.write(secrets.token_bytes(SECRET_BYTES))
            fh.flush()
            os.fsync(fh.fileno())
        try:
            os.link(tmp, path)  # fails if another process made one first: theirs is kept
        except FileExistsError:
            pass
        except OSError:  # a file system without hard links: renamed into place unless one appeared meanwhile
            if not path.exists():
                os.replace(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)
    if not path.exists():
        return None
    key = path.read_bytes()
    if len(key) != SECRET_BYTES:
        raise UntrustedFileError(f"the signing key {path} holds {len(key)} bytes, not {SECRET_BYTES}: delete it (the "
                                 "checkpoints it signed can then no longer be resumed)")
    return key


def write_signed_atomic(path, payload: bytes) -> None:
    """``payload`` behind a header and its HMAC-SHA256 under this account's key, written atomically
    (:func:`write_atomic`); :func:`read_signed` gives it back."""
    mac = hmac.new(_secret(create=True), SIGNED_HEADER + payload, hashlib.sha256).digest()
    write_atomic(Path(path), SIGNED_HEADER + mac + payload)


def read_signed(path, remedy: str) -> bytes:
    """The payload :func:`write_signed_atomic` wrote at ``path``, once its HMAC matches this account's key;
    :class:`~crowd_env.errors.UntrustedFileError` naming the file and ``remedy`` otherwise (an unsigned file, a
    file signed under another key, an altered one)."""
    data = Path(path).read_bytes()
    n = len(SIGNED_HEADER) + hashlib.sha256().digest_size
    if not data.startswith(SIGNED_HEADER) or len(data) < n:
        raise UntrustedFileError(f"{path} is not a file crowd_env signed (a plain pickle, as crowd_env wrote before "
                                 "it signed them, or another program's file): refused unread, as reading a pickle "
                                 f"runs the code it holds; {remedy}")
    key = _secret(create=False)
    want = hmac.new(key, data[:len(SIGNED_HEADER)] + data[n:], hashlib.sha256).digest() if key else b""
    if not hmac.compare_digest(data[len(SIGNED_HEADER):n], want):
        raise UntrustedFileError(f"{path} was not signed with this account's key ({secret_path()}): written by "
                                 f"someone else, elsewhere or altered since; refused unread; {remedy}")
    return data[n:]


def _digest_of(paths, key: bytes) -> str:
    """HMAC-SHA256 (hex) of the files ``paths`` (a folder: every file under it), each name and content length-
    prefixed, in order, a folder's files sorted by their relative path."""
    h = hmac.new(key, b"crowd_env files/1", hashlib.sha256)
    for top in map(Path, paths):
        files = sorted(p for p in top.rglob("*") if p.is_file()) if top.is_dir() else [top]
        for f in files:
            name = (top.name + "/" + f.relative_to(top).as_posix() if top.is_dir() else top.name).encode()
            h.update(len(name).to_bytes(8, "little") + name + f.stat().st_size.to_bytes(8, "little"))
            with open(f, "rb") as fh:
                for chunk in iter(lambda: fh.read(1 << 20), b""):
                    h.update(chunk)
    return h.hexdigest()


def files_digest(paths) -> str:
    """The digest under this account's key (made if needed) of the files ``paths`` (folders: every file under
    them), to keep beside them (a checkpoint's entry in its index) and check with :func:`check_files_digest`."""
    return _digest_of(paths, _secret(create=True))


def check_files_digest(paths, digest, remedy: str) -> None:
    """Nothing when ``digest`` is :func:`files_digest` of ``paths`` under this account's key; else
    :class:`~crowd_env.errors.UntrustedFileError` naming the files and ``remedy`` (no digest: files from before
    crowd_env signed them, or someone else's)."""
    key = _secret(create=False)
    names = ", ".join(str(p) for p in paths)
    if not isinstance(digest, str) or key is None or not hmac.compare_digest(digest, _digest_of(paths, key)):
        why = "carry no digest" if not isinstance(digest, str) else "do not match their digest under this account's key"
        raise UntrustedFileError(f"{names} {why} ({secret_path()}): written by someone else, elsewhere, before "
                                 f"crowd_env signed them, or altered since; refused unread, as loading them runs the "
                                 f"code they may hold; {remedy}")


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
