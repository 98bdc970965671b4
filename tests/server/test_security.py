"""Bind policy and CURVE: local by default, keys (or an explicit --insecure) otherwise.

Every socket these tests open is on loopback; the non-local addresses below are only
handed to the policy, which refuses them before anything is bound.
"""

from __future__ import annotations

import os
import stat
import sys
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray
from typer.testing import CliRunner

from reachwise.cli import serve as serve_cli
from reachwise.kinematics.robot import Robot
from reachwise.server.client import SceneClient, ServerUnavailable
from reachwise.server.security import (
    SecurityError,
    is_local,
    keygen,
    load_client_keys,
    load_server_keys,
    plan_bind,
)

from .conftest import HANG_GUARD, build_scene, crane_q, start_server

NON_LOCAL = [
    "tcp://0.0.0.0:0",
    "tcp://*:5590",
    "tcp://[::]:5590",
    "tcp://eth0:5590",
    "tcp://db.example:1",
    "udp://127.0.0.1:5",
]


@pytest.mark.parametrize(
    ("address", "local"),
    [
        ("ipc:///tmp/reachwise.sock", True),
        ("inproc://x", True),
        ("tcp://127.0.0.1:5590", True),
        ("tcp://127.3.2.1:5590", True),
        ("tcp://localhost:5590", True),
        ("tcp://[::1]:5590", True),
        ("tcp://127.0.0.1:*", True),
        ("ipc://", False),
        ("tcp://127.0.0.1", False),
        ("127.0.0.1:5590", False),
        ("tcp://10.0.0.1;127.0.0.1:5590", False),
    ]
    + [(a, False) for a in NON_LOCAL],
)
def test_is_local(address: str, local: bool) -> None:
    assert is_local(address) is local


@pytest.mark.parametrize("address", NON_LOCAL)
def test_non_local_bind_without_keys_is_refused(address: str) -> None:
    with pytest.raises(SecurityError, match=r"--keys DIR.*--insecure"):
        plan_bind(address, None, insecure=False)
    plan = plan_bind(address, None, insecure=True)  # a plan only: nothing is bound here
    assert not plan.local and not plan.curve


def test_cli_refuses_a_non_local_bind(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(sys, "argv", ["reachwise-serve", "--bind", "tcp://0.0.0.0:5590"])
    with pytest.raises(SystemExit) as info:
        serve_cli.main()
    assert info.value.code == 2
    assert "reachable from other machines" in capsys.readouterr().err


def test_keygen_files_and_permissions(tmp_path: Path) -> None:
    res = CliRunner().invoke(serve_cli.app, ["keygen", str(tmp_path / "keys")])
    assert res.exit_code == 0, res.output
    d = tmp_path / "keys"
    for name in ("server.key_secret", "client.key_secret"):
        assert stat.S_IMODE((d / name).stat().st_mode) == 0o600
    assert (d / "authorized" / "client.key").is_file()
    server = load_server_keys(d)
    client = load_client_keys(d)
    assert client.server == server.public and len(server.secret) == 40
    with pytest.raises(SecurityError, match="exist already"):
        keygen(d)
    plan = plan_bind("tcp://0.0.0.0:5590", d, insecure=False)  # keys make it acceptable
    assert plan.curve and not plan.local
    os.chmod(d / "server.key_secret", 0o644)
    with pytest.raises(SecurityError, match="readable by group or others"):
        load_server_keys(d)


def test_curve_server_accepts_only_authorized_clients(
    tmp_path: Path, crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    keys = tmp_path / "keys"
    keygen(keys)
    stranger = tmp_path / "stranger"
    keygen(stranger)
    proc = start_server(tmp_path / "srv", extra=("--keys", str(keys)))  # CURVE forced on loopback
    try:
        with SceneClient(proc.endpoint, keys=keys, deadline=HANG_GUARD) as client:
            assert client.wait_ready(30.0).ready
            build_scene(client, crane, clouds)
            client.set_joints(crane.name, crane_q(crane, 10))
            result = client.query_all()
            assert result.valid and len(result.pairs) > 0
        # no keys: the CURVE handshake never completes, so no reply ever comes
        with SceneClient(proc.endpoint, setup_deadline=0.5) as plain:
            with pytest.raises(ServerUnavailable):
                plain.hello()
        # keys the server has not authorized: refused by the ZAP handler
        with SceneClient(proc.endpoint, keys=stranger, setup_deadline=0.5) as other:
            with pytest.raises(ServerUnavailable):
                other.hello()
            missing = other.query_all(deadline=0.3)
            assert not missing.valid and "no reply" in missing.reason
    finally:
        status = proc.stop()
    assert status == 0, (proc.workdir / "server.log").read_text()


def test_a_bind_in_use_is_server_unavailable_naming_the_address() -> None:
    import zmq

    from reachwise import errors
    from reachwise.server.transport import CollisionServer

    ctx = zmq.Context.instance()
    taken = ctx.socket(zmq.ROUTER)
    taken.linger = 0
    port = taken.bind_to_random_port("tcp://127.0.0.1")
    address = f"tcp://127.0.0.1:{port}"
    try:
        with pytest.raises(errors.ServerUnavailable, match=address):
            CollisionServer(address).start()
    finally:
        taken.close(linger=0)


def test_an_unparsable_bind_is_an_input_error_naming_the_address() -> None:
    from reachwise.errors import InputError
    from reachwise.server.transport import CollisionServer

    with pytest.raises(InputError, match="tcp://no-such-host-name"):
        CollisionServer("tcp://no-such-host-name", insecure=True).start()


@pytest.mark.parametrize(("address", "code"), [("tcp://192.0.2.1:5591", 4), ("tcp://nonsense", 2)])
def test_cli_bind_failure_is_typed(
    address: str,
    code: int,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    # 192.0.2.1 (TEST-NET-1, RFC 5737) is on no host: binding it fails without binding
    monkeypatch.setattr(sys, "argv", ["reachwise-serve", "--bind", address, "--insecure"])
    with pytest.raises(SystemExit) as info:
        serve_cli.main()
    assert info.value.code == code
    err = capsys.readouterr().err
    assert f"cannot bind {address}" in err and "Traceback" not in err
