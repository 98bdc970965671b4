"""The command line's exit codes: each kind of reachwise error ends ``reachwise`` with its
own code and one line on stderr — bad input 2, missing optional package 3 (with the
install hint), unavailable collision server 4, any other reachwise error 1."""

from __future__ import annotations

import socket
import sys
from pathlib import Path

import pytest
import typer

import reachwise.cli as cli
from reachwise.errors import (
    InputError,
    MissingDependency,
    ReachwiseError,
    ServerUnavailable,
    UnknownName,
)
from reachwise.server.client import ServerError
from reachwise.server.client import ServerUnavailable as ClientServerUnavailable
from reachwise.server.protocol import ErrorCode, ProtocolError


def _run_main(
    argv: list[str], monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> tuple[int, str]:
    monkeypatch.setattr(sys, "argv", ["reachwise", *argv])
    with pytest.raises(SystemExit) as info:
        cli.main()
    code = info.value.code
    return (code if isinstance(code, int) else 1), capsys.readouterr().err.strip()


@pytest.mark.parametrize(
    ("error", "code"),
    [
        (InputError("robot.yaml", "joints[2].limits", "lower above upper"), 2),
        (UnknownName("--solver", "solver", "lm", ("dls", "trf")), 2),
        (MissingDependency("ompl", "plan", "the local-minimum escape"), 3),
        (ServerUnavailable("tcp://127.0.0.1:5590 not ready within 1 s"), 4),
        (ClientServerUnavailable("no reply from tcp://127.0.0.1:5590"), 4),
        (ServerError("describe: internal [internal]", ErrorCode.INTERNAL), 4),
        (ProtocolError(ErrorCode.BAD_MESSAGE, "id", "missing"), 1),
        (ReachwiseError("something reachwise could not do"), 1),
    ],
)
def test_each_error_kind_has_its_exit_code_and_one_line(
    error: ReachwiseError,
    code: int,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    app = typer.Typer()

    @app.command()
    def fail() -> None:
        raise error

    monkeypatch.setattr(cli, "app", app)
    got, err = _run_main([], monkeypatch, capsys)
    assert got == code == type(error).exit_code
    assert err == f"error: {error}"
    assert len(err.splitlines()) == 1 and "Traceback" not in err


def test_the_exit_codes_are_distinct_per_kind() -> None:
    codes = {
        c.exit_code for c in (ReachwiseError, InputError, MissingDependency, ServerUnavailable)
    }
    assert codes == {1, 2, 3, 4}
    assert issubclass(ServerError, ServerUnavailable)
    assert issubclass(ClientServerUnavailable, ServerUnavailable)
    assert not issubclass(ServerUnavailable, ValueError)  # not "bad input"


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_an_unreachable_server_exits_4_with_its_message(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    address = f"tcp://127.0.0.1:{_closed_port()}"
    argv = ["simulate", "p5-crane-obstacle", "--server", address, "--server-timeout", "0.5"]
    argv += ["--json", "--out", str(tmp_path / "sim")]  # --json: no progress bar on stderr
    code, err = _run_main(argv, monkeypatch, capsys)
    assert code == 4
    assert err == (
        f"error: {address} not ready within 0.5 s "
        f"(no reply to health from {address} within 500.0 ms)"
    )
    assert not (tmp_path / "sim").exists()


def test_a_missing_ray_backend_exits_3_with_the_install_hint(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    import trimesh.ray

    monkeypatch.setattr(trimesh.ray, "has_embree", False)  # the pure-numpy backend …
    monkeypatch.setitem(sys.modules, "rtree", None)  # … without rtree cannot cast rays
    out = tmp_path / "scan.ply"
    code, err = _run_main(["scan", "p5-floor-obstacle", "--out", str(out)], monkeypatch, capsys)
    assert code == 3
    assert err == (
        "error: trimesh's 'triangle' ray backend needs the optional package 'rtree': "
        'pip install "rtree"'
    )
    assert not out.exists()


def test_missing_embree_and_dask_name_what_to_install(monkeypatch: pytest.MonkeyPatch) -> None:
    import trimesh
    import trimesh.ray

    from reachwise.geometry.scanner import cast_rays
    from reachwise.synthesis.sweep import dask_executor

    monkeypatch.setattr(trimesh.ray, "has_embree", False)
    box = trimesh.creation.box()
    with pytest.raises(MissingDependency) as info:
        cast_rays(box, [[0.0, 0.0, 5.0]], [[0.0, 0.0, -1.0]], engine="embree")
    assert info.value.package == "embreex" and info.value.hint == 'pip install "embreex"'

    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(MissingDependency) as info, dask_executor("local", 1):
        pass
    assert str(info.value) == (
        "a sweep on a Dask cluster needs the optional package 'distributed': "
        'pip install "reachwise[cluster]"'
    )
    assert isinstance(info.value, ImportError)
