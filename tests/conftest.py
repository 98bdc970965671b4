"""Shared fixtures: random serial chains of both DH conventions, seeded."""

from __future__ import annotations

import signal

import numpy as np
import pytest

from reachwise.kinematics.robot import Joint, Robot
from reachwise.kinematics.transforms import pose_from_xyz_rpy

#: The headless-browser fixtures of the viewer and report tests.
pytest_plugins = ["tests.browser"]


def random_chain(rng: np.random.Generator, n_joints: int = 7, classic: bool = False) -> Robot:
    """A random chain mixing revolute, prismatic and fixed joints, random base and tool."""
    joints = []
    for i in range(n_joints):
        kind = rng.choice(["revolute", "revolute", "prismatic", "fixed"]) if i else "revolute"
        a, d = rng.uniform(-0.8, 0.8, 2)
        alpha, theta = rng.uniform(-np.pi, np.pi, 2)
        lim = (-0.5, 1.5) if kind == "prismatic" else (-np.pi, np.pi)
        joints.append(Joint(kind, a=a, alpha=alpha, d=d, theta=theta, limits=lim))
    base = pose_from_xyz_rpy(rng.uniform(-1, 1, 3), rng.uniform(-np.pi, np.pi, 3))
    tool = pose_from_xyz_rpy(rng.uniform(-0.3, 0.3, 3), rng.uniform(-np.pi, np.pi, 3))
    return Robot(
        "random",
        tuple(joints),
        convention="classic" if classic else "modified",
        base=base,
        tool=tool,
    )


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20171208)


#: Markers of the suite's longest files (minutes of CPU each, one fixture shared by their
#: tests): under pytest-xdist these files are handed out first.
FIRST_UNDER_XDIST = ("docs", "wheel", "memory_scenarios")


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """In a pytest-xdist worker (our ``addopts``: ``--dist loadfile
    --no-loadscope-reorder``, each file on one worker, files in collection order), move
    the longest files to the front, keeping the random order of everything else: a
    long file handed out last would keep one worker busy while the other idles. Every
    worker sorts the same collection the same way, as xdist requires. A run without
    workers keeps pytest-randomly's order as it is."""
    if not hasattr(config, "workerinput"):
        return
    items.sort(key=lambda item: not any(item.get_closest_marker(m) for m in FIRST_UNDER_XDIST))


def pytest_sessionstart(session: pytest.Session) -> None:
    """Print pytest-randomly's seed even under ``-q`` (its own header line is hidden
    there), so that a failing order can be replayed with ``pytest --randomly-seed=N``."""
    config = session.config
    if not config.pluginmanager.hasplugin("randomly"):
        return
    seed = config.getoption("randomly_seed", None)
    reporter = config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None and isinstance(seed, int):
        reporter.write_line(
            f"random test order, seed {seed} (replay: pytest --randomly-seed={seed})"
        )


def sigint_default() -> None:
    """``preexec_fn`` for a child the test will Ctrl-C: a shell that starts pytest in
    the background leaves SIGINT ignored, the child would inherit that and Python would
    then never raise KeyboardInterrupt."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
