"""An object's ``stamp`` given to ``add_object`` crosses the wire: a client's cloud
added with an old or an unknown time is stale under ``max_cloud_age`` on a real server
as in process (the same answers' ``cloud_stamps``), one added without a stamp never
ages, a refused stamp is a typed error, and a state directory keeps each stamp across
a restart."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from reachwise.benchmarks.server import ServerProcess
from reachwise.control.safety import SafetyConfig, check_data
from reachwise.distance.scene import Scene
from reachwise.distance.scene_types import SceneLike
from reachwise.errors import InputError
from reachwise.server.client import SceneClient

from .conftest import HANG_GUARD, start_server

#: Each object's stamp as added (s; inf: does not age, NaN: unknown).
STAMPS = {"cad": math.inf, "unknown": math.nan, "old": 2.0, "recent": 9.8}
NOW = 10.0
MAX_AGE = 0.5
PROBE = np.array([[0.0, 0.0, 0.0]])


def _build(scene: SceneLike, *, default: bool) -> None:
    """One probe and an object per :data:`STAMPS`, each watched against the probe;
    ``default``: "cad" is added without a stamp (the default)."""
    scene.add_object("probe", PROBE)
    for k, (name, stamp) in enumerate(STAMPS.items()):
        cloud = np.array([[1.0 + k, 0.0, 0.0]])
        if default and stamp == math.inf:
            scene.add_object(name, cloud)
        else:
            scene.add_object(name, cloud, stamp=stamp)
        scene.watch("probe", name, 0.1)


def _stale(stamps: object) -> set[str]:
    """The objects a controller with ``max_cloud_age`` refuses at :data:`NOW` (the rule
    of ``control.safety.check_data``)."""
    safety = SafetyConfig(dt=0.01, max_cloud_age=MAX_AGE)
    return {
        name
        for name in STAMPS
        if not check_data(
            1,
            NOW,
            None,
            NOW,
            safety,
            cloud_stamp=stamps[name],
            cloud=name,  # type: ignore[index]
        ).ok
    }


def _same_stamps(got: object, want: dict[str, float]) -> bool:
    return all(
        (math.isnan(v) and math.isnan(got[k])) or got[k] == v  # type: ignore[index]
        for k, v in want.items()
    )


def test_the_stamp_of_an_added_cloud_travels_to_the_server(tmp_path: Path) -> None:
    """In process and over a real server (with a mirroring client too) the answers
    carry each object's stamp; the old and the unknown one are stale, the one added
    without a stamp and the recent one are not. A server restarted on its state
    directory restores each stamp (the unknown one stays unknown, not "does not age")."""
    local = Scene()
    _build(local, default=True)
    want = local.query_all().cloud_stamps
    assert _same_stamps(want, STAMPS)
    assert _stale(want) == {"unknown", "old"}
    state = ("--state", str(tmp_path / "state"))
    first = start_server(tmp_path / "first", extra=state)
    try:
        with SceneClient(first.endpoint, deadline=HANG_GUARD, setup_deadline=HANG_GUARD) as c:
            _build(c, default=True)
            res = c.query_all()
            assert _same_stamps(res.cloud_stamps, STAMPS) and _stale(res.cloud_stamps) == {
                "unknown",
                "old",
            }
            assert [p.result.distance for p in res.pairs] == pytest.approx(
                [p.result.distance for p in local.query_all().pairs]
            )
    finally:
        assert first.stop() == 0, (first.workdir / "server.log").read_text()
    again = start_server(tmp_path / "again", extra=state)
    try:
        with SceneClient(again.endpoint, deadline=HANG_GUARD, setup_deadline=HANG_GUARD) as c:
            res = c.query_all()
            assert set(res.cloud_stamps) == {"probe", *STAMPS}
            assert _same_stamps(res.cloud_stamps, STAMPS)
            assert _stale(res.cloud_stamps) == {"unknown", "old"}
    finally:
        assert again.stop() == 0, (again.workdir / "server.log").read_text()
    local.close()


def test_a_mirroring_client_sends_the_stamps(server: ServerProcess) -> None:
    """A client that mirrors the scene adds each object to its copy and the server with
    its stamp (every one given explicitly, +inf included)."""
    with SceneClient(
        server.endpoint, deadline=HANG_GUARD, setup_deadline=HANG_GUARD, mirror=True
    ) as c:
        c.clear()
        _build(c, default=False)
        assert set(c.objects) == {"probe", *STAMPS}
        res = c.query_all()
        assert _same_stamps(res.cloud_stamps, STAMPS) and _stale(res.cloud_stamps) == {
            "unknown",
            "old",
        }


def test_a_bad_stamp_is_refused_before_it_is_sent(server: ServerProcess) -> None:
    with SceneClient(server.endpoint, deadline=HANG_GUARD, setup_deadline=HANG_GUARD) as c:
        c.clear()
        for bad in (-math.inf, "now", True):
            with pytest.raises(InputError, match="stamp"):
                c.add_object("bad", PROBE, stamp=bad)  # type: ignore[arg-type]
        assert "bad" not in c.describe().objects
