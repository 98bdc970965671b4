"""A scenario runs in three stages: *resolve* reads every file once, *build* and *run*
read none. Built and run with every file access refused (``open``, ``Path.open``,
``Path.read_text``/``read_bytes``, ``trimesh.load``/``load_mesh``, ``numpy.load``
patched to record the attempt and raise), a resolved scenario's log equals the log of
the same run with files allowed, and of ``reachwise.simulate``. The blocker is itself
shown to catch the resolve stage reading its files."""

from __future__ import annotations

import builtins
import contextlib
import dataclasses
import pathlib
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
import trimesh

import reachwise
from reachwise.errors import RobotFileError
from reachwise.io.meshes import _CACHE as mesh_cache
from reachwise.sim.log import SimulationLog
from reachwise.sim.resolve import ResolvedScenario, resolve_scenario
from reachwise.sim.simulate import run_world
from reachwise.sim.world import SimClock, build_world
from tests._real_arms import needs_erd

DURATION = 2.0  # s: 201 ticks at the scenarios' dt = 0.01 s


class FileAccess(OSError):
    """A file was touched while files were blocked."""


@contextlib.contextmanager
def files_blocked() -> Iterator[list[str]]:
    """Every file access raises :class:`FileAccess`; the attempts are listed too, so an
    access whose error the code caught and went past is still seen."""
    attempts: list[str] = []

    def refuse(what: str) -> Any:
        def blocked(*args: Any, **kwargs: Any) -> Any:
            attempts.append(f"{what}{args[:1]!r}")
            raise FileAccess(f"{what} while files are blocked: {args[:1]!r}")

        return blocked

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(builtins, "open", refuse("open"))
        mp.setattr(pathlib.Path, "open", refuse("Path.open"))
        mp.setattr(pathlib.Path, "read_text", refuse("Path.read_text"))
        mp.setattr(pathlib.Path, "read_bytes", refuse("Path.read_bytes"))
        mp.setattr(trimesh, "load", refuse("trimesh.load"))
        mp.setattr(trimesh, "load_mesh", refuse("trimesh.load_mesh"))
        mp.setattr(np, "load", refuse("numpy.load"))
        yield attempts


def build_and_run(resolved: ResolvedScenario) -> SimulationLog:
    """Stages two and three: the world from ``resolved`` alone, then the loop."""
    clock = SimClock()
    world = build_world(resolved, clock=clock)
    return run_world(world, clock, duration=DURATION)


def assert_same_log(a: SimulationLog, b: SimulationLog) -> None:
    """Every field of the two logs equal (arrays bit for bit, NaN equal to NaN)."""
    for f in dataclasses.fields(SimulationLog):
        x, y = getattr(a, f.name), getattr(b, f.name)
        _assert_same(x, y, f.name)


def _assert_same(x: Any, y: Any, where: str) -> None:
    if isinstance(x, dict):
        assert isinstance(y, dict) and x.keys() == y.keys(), where
        for k in x:
            _assert_same(x[k], y[k], f"{where}.{k}")
    elif isinstance(x, np.ndarray):
        assert isinstance(y, np.ndarray) and x.shape == y.shape, where
        if x.dtype.kind in "fc":
            assert np.array_equal(x, y, equal_nan=True), where
        else:
            assert np.array_equal(x, y), where
    else:
        assert x == y, where


SCENARIOS = [
    "p5-crane-obstacle",  # built-in robot and a scanned obstacle (rescans at run time)
    "panda-person-camera",  # a depth camera: surfaces of objects and links
    pytest.param("panda-shelf", marks=needs_erd),  # a real URDF with meshes
]


@pytest.mark.parametrize("name", SCENARIOS)
def test_build_and_run_read_no_file_and_log_the_same(name: str) -> None:
    resolved = resolve_scenario(name)
    free = build_and_run(resolved)
    mesh_cache.clear()  # a cached mesh is found by its file's size and time: none now
    with files_blocked() as attempts:
        blocked = build_and_run(resolved)
    assert attempts == []
    assert len(blocked.t) > 100
    assert_same_log(blocked, free)
    assert_same_log(reachwise.simulate(name, duration=DURATION), free)


@needs_erd
def test_a_mujoco_plant_builds_from_the_resolved_meshes() -> None:
    """The MuJoCo plant's link inertias come from meshes read at resolve: a real-URDF
    scenario builds and runs on it with every file blocked, logging what the unblocked
    run logs; without the resolved meshes the build would read the mesh files."""
    pytest.importorskip("mujoco")
    resolved = resolve_scenario("panda-shelf")
    meshes = next(iter(resolved.link_meshes.values()))
    assert len(meshes) >= 7  # every panda link with a mesh shape

    def run(res: ResolvedScenario) -> SimulationLog:
        clock = SimClock()
        world = build_world(res, plant="mujoco", clock=clock)
        return run_world(world, clock, duration=0.5)

    free = run(resolved)
    mesh_cache.clear()  # a cached mesh is found by its file's size and time: none now
    with files_blocked() as attempts:
        blocked = run(resolved)
    assert attempts == []
    assert_same_log(blocked, free)
    unread = dataclasses.replace(resolved, link_meshes={})
    mesh_cache.clear()
    with files_blocked() as attempts, pytest.raises(RobotFileError):
        run(unread)
    assert attempts  # the check sees a build that reads the meshes


def test_the_blocker_catches_the_resolve_stage_reading_files() -> None:
    with files_blocked() as attempts, pytest.raises(FileAccess):
        resolve_scenario("p5-crane-obstacle")
    assert attempts


def test_a_resolved_scenario_is_frozen_and_resolving_it_again_returns_it() -> None:
    resolved = resolve_scenario("p5-crane-obstacle")
    assert resolve_scenario(resolved) is resolved
    with pytest.raises(dataclasses.FrozenInstanceError):
        resolved.robots = {}  # type: ignore[misc]
    with pytest.raises(TypeError):
        resolved.robots["crane"] = resolved.robots["crane"]  # type: ignore[index]
