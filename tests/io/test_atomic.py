"""The one atomic writer: concurrent writers never leave a torn file, a failure mid-write
leaves the old file and no temporary file, the data is fsync'ed before the rename, and no
other module of the package writes a file behind its back."""

from __future__ import annotations

import ast
import os
import threading
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import reachwise
from reachwise.io.atomic import TEMP_SUFFIX, atomic_open, atomic_write

SRC = Path(reachwise.__file__).parent


def _contents(n: int, size: int) -> list[bytes]:
    """``n`` distinct payloads of ``size`` bytes, each a repeated marker byte."""
    return [bytes([65 + i]) * size for i in range(n)]


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(TEMP_SUFFIX))


def _hammer(write: Callable[[Path, bytes], None], target: Path, payloads: list[bytes]) -> set[str]:
    """Writers (one thread per payload, 20 writes each) and a reader on one path; return
    what went wrong: torn reads, or exceptions of the writers."""
    problems: set[str] = set()
    stop = threading.Event()

    def writer(data: bytes) -> None:
        try:
            for _ in range(20):
                write(target, data)
        except Exception as exc:
            problems.add(f"writer failed: {type(exc).__name__}")

    def reader() -> None:
        while not stop.is_set():
            try:
                seen = target.read_bytes()
            except FileNotFoundError:
                continue
            if seen not in payloads:
                problems.add(f"torn read of {len(seen)} bytes")

    threads = [threading.Thread(target=writer, args=(d,)) for d in payloads]
    r = threading.Thread(target=reader)
    r.start()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    stop.set()
    r.join()
    if target.read_bytes() not in payloads:
        problems.add("final file torn")
    return problems


def test_concurrent_writers_to_one_path_never_leave_a_torn_file(tmp_path: Path) -> None:
    target = tmp_path / "shared.bin"
    target.write_bytes(b"old")
    payloads = [b"old", *_contents(4, 1 << 20)]
    assert _hammer(lambda p, d: atomic_write(p, d), target, payloads) == set()
    assert _leftovers(tmp_path) == []


def test_interleaved_writers_each_commit_a_whole_file(tmp_path: Path) -> None:
    """Two writers open the same path, write in turns, and close in the reverse order:
    each commits its own complete file (the last to close wins), no temp is shared."""
    target = tmp_path / "f.txt"
    with atomic_open(target, "w") as a:
        a.write("A" * 1000)
        with atomic_open(target, "w") as b:
            b.write("B" * 500)
            a.write("A" * 1000)
            b.write("B" * 500)
        assert target.read_text() == "B" * 1000
        a.write("A" * 1000)
    assert target.read_text() == "A" * 3000
    assert _leftovers(tmp_path) == []


def _fixed_name_writer(path: Path, data: bytes) -> None:
    """The helper the package used to copy around: one fixed ``.tmp`` name per target."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def test_the_interleaving_check_catches_a_fixed_temporary_name(tmp_path: Path) -> None:
    """Judge the judge: the same interleaving breaks the old fixed-name helper, so the
    test above can fail: writer B renames the temp file writer A is still writing, A
    goes on writing into the published file (torn: half B's, half A's), and A's own
    rename finds its temp file gone."""
    target = tmp_path / "f.txt"
    tmp = target.with_name(target.name + ".tmp")
    with open(tmp, "wb", buffering=0) as a:  # writer A is half-way through its temp file …
        a.write(b"A" * 10)
        _fixed_name_writer(target, b"B" * 20)  # … when writer B writes and renames it
        a.write(b"A" * 10)
    assert target.read_bytes() == b"B" * 10 + b"A" * 10
    with pytest.raises(FileNotFoundError):
        os.replace(tmp, target)


def test_a_failure_mid_write_leaves_the_old_file_and_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "design.yaml"
    target.write_text("old content\n")
    with pytest.raises(RuntimeError, match="disk on fire"), atomic_open(target, "w") as fh:
        fh.write("new content, half of it")
        raise RuntimeError("disk on fire")
    assert target.read_text() == "old content\n"
    assert _leftovers(tmp_path) == []


def test_a_failed_rename_leaves_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "occupied"
    target.mkdir()
    (target / "inside").write_text("x")  # a non-empty folder cannot be replaced by a file
    with pytest.raises(OSError):
        atomic_write(target, b"data")
    assert (target / "inside").read_text() == "x"
    assert _leftovers(tmp_path) == []


def test_data_and_folder_are_fsynced_before_and_after_the_rename(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    events: list[str] = []
    real_fsync, real_replace = os.fsync, os.replace

    def fsync(fd: int) -> None:
        events.append("fsync-dir" if os.path.isdir(f"/proc/self/fd/{fd}") else "fsync-file")
        real_fsync(fd)

    def replace(a: str | os.PathLike[str], b: str | os.PathLike[str]) -> None:
        events.append("replace")
        real_replace(a, b)

    monkeypatch.setattr(os, "fsync", fsync)
    monkeypatch.setattr(os, "replace", replace)
    atomic_write(tmp_path / "f.json", "{}")
    if not Path("/proc/self/fd").is_dir():
        pytest.skip("needs /proc to tell a folder's descriptor from a file's")
    assert events == ["fsync-file", "replace", "fsync-dir"]


def test_new_files_get_the_usual_permissions(tmp_path: Path) -> None:
    mask = os.umask(0)
    os.umask(mask)
    path = atomic_write(tmp_path / "report.html", "<html></html>")
    assert path.stat().st_mode & 0o777 == 0o666 & ~mask
    assert path.read_text() == "<html></html>"


def test_text_mode_keeps_newline_and_encoding(tmp_path: Path) -> None:
    with atomic_open(tmp_path / "a.csv", "w", newline="") as fh:
        fh.write("x,y\r\nä,1\r\n")
    assert (tmp_path / "a.csv").read_bytes() == "x,y\r\nä,1\r\n".encode()
    with atomic_open(tmp_path / "a.npy", "wb") as fh:
        np.save(fh, np.arange(3.0))
    np.testing.assert_array_equal(np.load(tmp_path / "a.npy"), np.arange(3.0))


def test_a_bad_mode_is_refused_before_any_file_is_made(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="mode"), atomic_open(tmp_path / "f", "a"):  # type: ignore[arg-type]
        pass
    assert list(tmp_path.iterdir()) == []


# ---- every writer of the package goes through it ------------------------------------

_WRITE_MODES = ("w", "x")
_NP_SAVES = ("save", "savez", "savez_compressed", "savetxt")


def _direct_writes(tree: ast.AST) -> list[str]:
    """Calls that write a file without the atomic writer: ``.write_text``,
    ``.write_bytes``, ``os.replace``/``os.rename``, ``open``/``Path.open`` for writing,
    ``np.save*`` given a path string or ``Path`` expression, ``savefig`` without
    ``format=`` (that is, to a file name)."""
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        f = node.func
        name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""
        owner = ast.unparse(f.value) if isinstance(f, ast.Attribute) else ""
        if name in ("write_text", "write_bytes") or (
            owner == "os" and name in ("replace", "rename")
        ):
            found.append(f"line {node.lineno}: {ast.unparse(f)}")
        elif name == "open" and owner not in ("os",):
            modes = [a for a in node.args if isinstance(a, ast.Constant)]
            modes += [k.value for k in node.keywords if k.arg == "mode"]
            if any(isinstance(m, ast.Constant) and str(m.value)[:1] in _WRITE_MODES for m in modes):
                found.append(f"line {node.lineno}: {ast.unparse(node)}")
        elif name == "savefig" and not any(k.arg == "format" for k in node.keywords):
            found.append(f"line {node.lineno}: {ast.unparse(node)}")  # format from a file name
        elif owner in ("np", "numpy") and name in _NP_SAVES and node.args:
            target = node.args[0]
            if isinstance(target, ast.Constant) or (
                isinstance(target, ast.BinOp) and isinstance(target.op, ast.Div)
            ):
                found.append(f"line {node.lineno}: {ast.unparse(node)}")
    return found


def test_the_scan_finds_direct_writes() -> None:
    """Judge the judge: each way of writing a file past the atomic writer is found."""
    bad = """
Path(p).write_text(s)
p.write_bytes(b)
os.replace(tmp, p)
with open(p, "w") as fh: pass
with (out / "log.csv").open("w", newline="") as fh: pass
np.savez_compressed(out / "log.npz", **arrays)
fig.savefig(folder / "x.png", dpi=110)
fig.savefig(p, dpi=110)
"""
    ok = """
with open(p) as fh: pass
with open(p, "rb") as fh: pass
with atomic_open(p, "wb") as fh: np.save(fh, a); fig.savefig(fh, format="png")
fig.savefig(buf, format="png")
os.open(folder, os.O_RDONLY)
"""
    assert len(_direct_writes(ast.parse(bad))) == 8
    assert _direct_writes(ast.parse(ok)) == []


def test_no_module_writes_a_file_past_the_atomic_writer() -> None:
    offenders = {}
    for path in sorted(SRC.rglob("*.py")):
        if path == SRC / "io" / "atomic.py":
            continue
        hits = _direct_writes(ast.parse(path.read_text(), str(path)))
        if hits:
            offenders[str(path.relative_to(SRC))] = hits
    assert offenders == {}
