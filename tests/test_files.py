"""Every file crowd_env writes goes through :mod:`crowd_env.files` (a temporary name, fsync, rename): a
killed run never leaves half a table, record, figure or policy under its final name. A scan of the package's
source finds any write that bypasses it; the writers themselves are checked here."""
from __future__ import annotations

import ast
import csv
import io
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from crowd_env import files
from crowd_env.errors import InputError

PACKAGE = Path(__file__).resolve().parents[1] / "crowd_env"

# Writes that stream to a temporary name and rename it themselves, with the reason they cannot be one buffer.
STREAMED = {
    ("experiments/output/video.py", "imopen"): "frames stream to the encoder; the partial file is renamed at close",
    ("experiments/output/video.py", "get_writer"): "the same, for the ffmpeg writer",
}
_WRITE_METHODS = {"write_text", "write_bytes", "savefig", "to_csv", "imwrite"}
_IN_MEMORY = ("buffer", "text")  # the names the package gives its io.BytesIO / io.StringIO buffers
_WRITE_FUNCTIONS = {("json", "dump"), ("np", "save"), ("np", "savez"), ("np", "savez_compressed"), ("np", "savetxt"),
                    ("pickle", "dump"), ("shutil", "copyfile"), ("shutil", "copy"), ("shutil", "copy2"),
                    ("shutil", "copytree"), ("shutil", "move")}


def _writes(tree: ast.AST):
    """(line, what) of every call in ``tree`` that writes a file by itself: ``open`` with a writing mode, and the
    methods and functions above (a write into an in-memory buffer is a call on ``io`` objects, which the helpers
    of crowd_env.files then write)."""
    for node in sorted((n for n in ast.walk(tree) if isinstance(n, ast.Call)), key=lambda n: (n.lineno, n.col_offset)):
        f = node.func
        target = node.args[0] if node.args else None
        if isinstance(f, ast.Name) and f.id == "open" or isinstance(f, ast.Attribute) and f.attr == "open":
            mode = node.args[1] if len(node.args) > 1 else next((k.value for k in node.keywords if k.arg == "mode"), None)
            if isinstance(mode, ast.Constant) and isinstance(mode.value, str) and set(mode.value) & set("wax+"):
                yield node.lineno, f"open(..., {mode.value!r})"
        elif isinstance(target, ast.Name) and target.id in _IN_MEMORY:
            continue  # into an in-memory buffer
        elif isinstance(f, ast.Attribute):
            owner = f.value.id if isinstance(f.value, ast.Name) else None
            if (owner, f.attr) in _WRITE_FUNCTIONS:
                yield node.lineno, f"{owner}.{f.attr}"
            elif f.attr in _WRITE_METHODS:
                yield node.lineno, f".{f.attr}(...)"
            elif f.attr in ("imopen", "get_writer"):
                yield node.lineno, f.attr


def test_every_file_write_of_the_package_goes_through_crowd_env_files():
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).as_posix()
        if rel == "files.py":
            continue
        for line, what in _writes(ast.parse(path.read_text(encoding="utf-8"))):
            if not any(rel == r and what.startswith(w) for r, w in STREAMED):
                found.append(f"crowd_env/{rel}:{line}: {what}")
    assert not found, "writes that bypass crowd_env.files (use its atomic writers):\n" + "\n".join(found)


def test_the_scan_finds_a_bare_write():
    """The scan above is not blind: each kind of bare write is found."""
    source = "\n".join([
        "open(p, 'w').write(x)", "open(p, mode='a')", "path.write_text(x)", "fig.savefig(p)", "json.dump(v, fh)",
        "np.save(p, a)", "shutil.copyfile(a, b)", "open(p).read()", "fig.savefig(buffer, format='png')"])
    found = [what for _, what in _writes(ast.parse(source))]
    assert found == ["open(..., 'w')", "open(..., 'a')", ".write_text(...)", ".savefig(...)", "json.dump", "np.save",
                     "shutil.copyfile"]


def test_csv_rows_as_dicts_or_sequences_and_a_short_row_named(tmp_path):
    path = tmp_path / "t.csv"
    files.write_csv_atomic(path, ["a", "b"], [{"a": 1, "b": 2.5}, [3, "x"], (np.float64(0.1), True)])
    assert list(csv.reader(io.StringIO(path.read_text()))) == [["a", "b"], ["1", "2.5"], ["3", "x"], ["0.1", "True"]]
    with pytest.raises(InputError, match=r"row 1 of .*t2.csv has 1 values for 2 columns"):
        files.write_csv_atomic(tmp_path / "t2.csv", ["a", "b"], [[1, 2], [3]])
    assert not (tmp_path / "t2.csv").exists()  # nothing under the final name
    assert not list(tmp_path.glob(".*tmp"))


def test_a_figure_and_a_copy_are_written_whole(tmp_path):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(2, 2))
    FigureCanvasAgg(fig)
    fig.add_subplot(1, 1, 1).plot([0, 1], [1, 0])
    png = files.save_figure_atomic(fig, tmp_path / "sub" / "f.png", dpi=50)
    assert Path(png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    svg = files.save_figure_atomic(fig, tmp_path / "f.svg")
    assert b"<svg" in Path(svg).read_bytes()
    files.copy_atomic(png, tmp_path / "g.png")
    assert (tmp_path / "g.png").read_bytes() == Path(png).read_bytes()
    assert not list(tmp_path.rglob(".*tmp"))


def test_text_is_utf8_whatever_the_locale(tmp_path):
    """In a process whose locale encoding is ASCII (the C locale, without UTF-8 mode or locale coercion), where a
    plain open(..., "w") cannot write "ρ", the writers still write UTF-8."""
    code = ("import locale, sys; from crowd_env import files; "
            "assert locale.getpreferredencoding(False).lower() in ('ascii', 'ansi_x3.4-1968'), "
            "locale.getpreferredencoding(False); "
            "files.write_atomic(sys.argv[1], '\\u03c1 = 2 /m\\u00b2, \\u03a6'); "
            "files.write_json_atomic(sys.argv[2], {'\\u03c1': [1, 2]}, ensure_ascii=False)")  # an ASCII command line
    env = {**os.environ, "LC_ALL": "C", "LANG": "C", "PYTHONUTF8": "0", "PYTHONCOERCECLOCALE": "0"}
    out = subprocess.run([sys.executable, "-c", code, str(tmp_path / "u.md"), str(tmp_path / "j.json")], env=env,
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert (tmp_path / "u.md").read_bytes().decode("utf-8") == "ρ = 2 /m², Φ"
    assert json.loads((tmp_path / "j.json").read_bytes().decode("utf-8")) == {"ρ": [1, 2]}


def test_a_signed_file_reads_back_and_anything_else_is_refused_unread(tmp_path, monkeypatch):
    """read_signed gives back what write_signed_atomic wrote under this account's key (made on first use, mode
    0600, outside the file's folder); an unsigned pickle, a file signed under another key and an altered one are
    refused before anything in them is unpickled, naming the file and the remedy."""
    import pickle

    from crowd_env.errors import UntrustedFileError
    from tests.conftest import CodeRunningPayload

    monkeypatch.setenv(files.SECRET_FILE_ENV, str(tmp_path / "keys" / "mine.key"))
    path = tmp_path / "run" / "c.pkl"
    path.parent.mkdir()
    files.write_signed_atomic(path, b"payload")
    assert files.read_signed(path, "delete it") == b"payload"
    assert (tmp_path / "keys" / "mine.key").stat().st_mode & 0o777 == 0o600
    flag = tmp_path / "ran.flag"
    path.write_bytes(pickle.dumps(CodeRunningPayload(flag)))  # someone else's plain pickle
    with pytest.raises(UntrustedFileError, match=r"c.pkl is not a file crowd_env signed.*refused unread.*delete it"):
        files.read_signed(path, "delete it")
    files.write_signed_atomic(path, pickle.dumps(CodeRunningPayload(flag)))  # signed, but under another key
    monkeypatch.setenv(files.SECRET_FILE_ENV, str(tmp_path / "keys" / "other.key"))
    with pytest.raises(UntrustedFileError, match=r"c.pkl was not signed with this account's key"):
        files.read_signed(path, "delete it")
    assert not (tmp_path / "keys" / "other.key").exists()  # reading never makes a key
    files.write_signed_atomic(path, b"payload")
    data = bytearray(path.read_bytes())
    data[-1] ^= 1  # one bit of the payload changed
    path.write_bytes(bytes(data))
    with pytest.raises(UntrustedFileError, match="was not signed with this account's key"):
        files.read_signed(path, "delete it")
    assert not flag.exists()


def test_a_files_digest_covers_names_and_contents_of_files_and_folders(tmp_path, monkeypatch):
    from crowd_env.errors import UntrustedFileError

    monkeypatch.setenv(files.SECRET_FILE_ENV, str(tmp_path / "mine.key"))
    (tmp_path / "ck" / "sub").mkdir(parents=True)
    (tmp_path / "ck" / "sub" / "a.pkl").write_bytes(b"aa")
    (tmp_path / "m.zip").write_bytes(b"zz")
    paths = [tmp_path / "m.zip", tmp_path / "ck"]
    digest = files.files_digest(paths)
    files.check_files_digest(paths, digest, "retrain")
    for change in (lambda: (tmp_path / "ck" / "sub" / "b.pkl").write_bytes(b""),  # a file added to the folder
                   lambda: (tmp_path / "m.zip").write_bytes(b"zy")):  # a file altered
        change()
        with pytest.raises(UntrustedFileError, match=r"m.zip, .*ck do not match their digest.*retrain"):
            files.check_files_digest(paths, digest, "retrain")
        digest = files.files_digest(paths)
    with pytest.raises(UntrustedFileError, match="carry no digest"):
        files.check_files_digest(paths, None, "retrain")
    monkeypatch.setenv(files.SECRET_FILE_ENV, str(tmp_path / "other.key"))
    with pytest.raises(UntrustedFileError, match="do not match"):
        files.check_files_digest(paths, digest, "retrain")


def test_the_key_is_made_once_also_where_the_file_system_has_no_hard_links(tmp_path, monkeypatch):
    monkeypatch.setenv(files.SECRET_FILE_ENV, str(tmp_path / "k" / "secret.key"))
    files.write_signed_atomic(tmp_path / "a", b"a")
    key = (tmp_path / "k" / "secret.key").read_bytes()

    def no_links(*args):
        raise OSError("hard links not supported")

    monkeypatch.setattr(os, "link", no_links)
    files.write_signed_atomic(tmp_path / "b", b"b")  # the key exists: kept
    assert (tmp_path / "k" / "secret.key").read_bytes() == key and files.read_signed(tmp_path / "a", "") == b"a"
    monkeypatch.setenv(files.SECRET_FILE_ENV, str(tmp_path / "k2" / "secret.key"))
    files.write_signed_atomic(tmp_path / "c", b"c")  # made by renaming
    assert files.read_signed(tmp_path / "c", "") == b"c" and os.listdir(tmp_path / "k2") == ["secret.key"]
