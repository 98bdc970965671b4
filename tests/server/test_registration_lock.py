"""Registering an object builds its spatial index outside the service's scene lock.

Building a large cloud's index is slow (P-V Table 1 steps 1-3); the service builds it
before it takes the lock that queries and binary ticks need, so a registration never
holds up the answers of the pairs already watched. The test looks from another thread
while the build runs: the lock is free and a query of every watched pair is answered.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

import reachwise.server.service_core as core
from reachwise.geometry.cloud import PointCloud
from reachwise.kinematics.robot import Robot
from reachwise.server import protocol as P
from reachwise.server.service import SceneService

from .conftest import LINKS, box_points, crane_q
from .lock_probe import from_another_thread


def _watched_crane(crane: Robot, clouds: dict[str, NDArray[np.float64]]) -> SceneService:
    svc = SceneService(clock=lambda: 1000.0)
    svc.handle(P.OperationCall.of("add_robot", crane, crane_q(crane, 0), stamp=1.0))
    for link in LINKS:
        svc.handle(P.AddObject(link, clouds[link], None, crane.name, link))
    env = np.eye(4)
    env[0, 3] = 1.6
    svc.handle(P.AddObject("environment", clouds["environment"], env))
    svc.handle(P.OperationCall.of("watch_environment", crane.name, 1.5))
    return svc


def test_an_object_index_is_built_outside_the_scene_lock(
    crane: Robot, clouds: dict[str, NDArray[np.float64]], monkeypatch: pytest.MonkeyPatch
) -> None:
    svc = _watched_crane(crane, clouds)
    before = svc.handle(P.Query(2.0))
    assert isinstance(before, P.QueryReply)
    during: list[tuple[str, bool, P.Reply | None]] = []
    build = core.cloud_index

    def observed(cloud: PointCloud) -> object:
        during.append((cloud.name, *from_another_thread(svc)))
        return build(cloud)

    monkeypatch.setattr(core, "cloud_index", observed)
    box = box_points((0.3, 0.3, 0.3), 400, 11)
    svc.handle(P.AddObject("crate", box, np.eye(4)))

    assert [name for name, _, _ in during] == ["crate"]
    _, free, answer = during[0]
    assert free
    assert isinstance(answer, P.QueryReply)
    assert answer.pairs == before.pairs  # the pairs watched before the registration
    np.testing.assert_array_equal(answer.rows[:, 0], before.rows[:, 0])
    assert "crate" in svc.scene.objects  # the registration went on after the build


def test_the_lock_check_sees_a_held_lock(
    crane: Robot, clouds: dict[str, NDArray[np.float64]]
) -> None:
    """The check above would catch a build under the lock: with the lock held by the
    registering thread, the other thread finds it taken."""
    svc = _watched_crane(crane, clouds)
    with svc.lock:
        free, answer = from_another_thread(svc)
    assert not free and answer is None
