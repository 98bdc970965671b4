"""Shared fixtures of the collision server tests: a small crane scene and real server
processes on loopback (each stops by itself: SIGTERM at teardown, --max-runtime as a
backstop)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

import reachwise
from reachwise.benchmarks.server import ServerProcess
from reachwise.kinematics.robot import Robot
from reachwise.server.client import SceneLike

#: Caps of the test servers: small, so that oversized input is cheap to send.
MAX_CLOUD_POINTS = 20_000
MAX_MESSAGE_MB = 1.0
#: No test server lives longer than this (s), whatever happens to the test.
MAX_RUNTIME = 240.0
LINKS = ("link_2", "link_3", "link_6")
#: Reply deadline (s) of the clients that talk to a healthy test server: only a hang
#: guard. A loopback reply takes about 50 µs; a loaded machine must not turn a slow one
#: into "missing data" and a failed test. (Tests that expect no reply at all use short
#: deadlines: no reply can come, so those never depend on the machine's speed.)
HANG_GUARD = 60.0


def box_points(size: tuple[float, float, float], n: int, seed: int) -> NDArray[np.float64]:
    """``n`` points on the surface of a centred box (seeded)."""
    rng = np.random.default_rng(seed)
    half = np.asarray(size) / 2
    pts = rng.uniform(-half, half, (n, 3))
    axis = rng.integers(0, 3, n)
    pts[np.arange(n), axis] = np.where(rng.random(n) < 0.5, -1.0, 1.0) * half[axis]
    return pts


@pytest.fixture(scope="session")
def crane() -> Robot:
    return reachwise.load_robot("hiab-xs033")


@pytest.fixture(scope="session")
def clouds() -> dict[str, NDArray[np.float64]]:
    """Link parts (300 points each) and a floor-with-obstacle environment."""
    floor = box_points((2.5, 2.0, 0.02), 1500, seed=7)
    obstacle = box_points((0.6, 0.6, 0.45), 500, seed=8) + np.array([0.3, 0.0, 0.225])
    return {
        "link_2": box_points((2.0, 0.2, 0.15), 300, seed=1) + np.array([1.1, 0.0, 0.0]),
        "link_3": box_points((0.18, 1.6, 0.14), 300, seed=2) + np.array([0.0, 0.85, 0.0]),
        "link_6": box_points((0.7, 0.5, 0.4), 300, seed=3) + np.array([0.6, 0.0, 0.0]),
        "environment": np.vstack([floor, obstacle]),
    }


def crane_q(robot: Robot, k: int) -> NDArray[np.float64]:
    """A smooth joint path (tick k at 100 Hz), the grabber hanging."""
    t = k / 100.0
    q = np.zeros(robot.n)
    q[0] = 0.5 * np.sin(0.8 * t)
    q[1] = 0.25 + 0.2 * np.sin(0.5 * t)
    q[2] = -0.9 + 0.3 * np.sin(0.4 * t)
    q[3] = 0.6
    q[4] = q[1] + q[2]
    return q


def build_scene(scene: SceneLike, robot: Robot, clouds: dict[str, NDArray[np.float64]]) -> None:
    """Register the crane, its parts, the environment 3.4 m out and the pair rules."""
    scene.add_robot(robot, crane_q(robot, 0))
    for link in LINKS:
        scene.add_object(link, clouds[link], robot=robot.name, link=link)
    env_pose = np.eye(4)
    env_pose[0, 3] = 3.4
    scene.add_object("environment", clouds["environment"], env_pose)
    scene.watch_environment(robot.name, 1.5)
    scene.watch_self(robot.name, 0.5)


def start_server(
    workdir: Path, *, bind: str = "tcp://127.0.0.1:*", extra: tuple[str, ...] = ()
) -> ServerProcess:
    """A started server process (``reachwise serve``) with small caps."""
    workdir.mkdir(parents=True, exist_ok=True)
    caps = ("--max-cloud-points", str(MAX_CLOUD_POINTS), "--max-message-mb", str(MAX_MESSAGE_MB))
    return ServerProcess(workdir, MAX_RUNTIME, bind=bind, extra=caps + extra).__enter__()


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServerProcess]:
    """One server process for a test module; it must stop cleanly at teardown."""
    proc = start_server(tmp_path_factory.mktemp("server"))
    try:
        yield proc
    finally:
        status = proc.stop()
    assert status == 0, (proc.workdir / "server.log").read_text()
