"""The scene memory in the viewer: rebuilt from the cameras' frames, it is the map the
simulation's controller queried, whichever way the playback seeks."""

from __future__ import annotations

import numpy as np
import pytest

from reachwise.distance.scene_memory import STATES, SceneMemory
from reachwise.errors import InputError
from reachwise.sim.log import SimulationLog
from reachwise.sim.simulate import run_world
from reachwise.sim.world import SimClock, World, build_world
from reachwise.viz.memory_replay import MAX_SNAPSHOTS, MemoryReplay
from reachwise.viz.memory_voxels import MAX_VOXELS_SHOWN
from reachwise.viz.playback import Playback
from reachwise.viz.scene_data import voxel_centres
from reachwise.viz.viewer import Viewer

SCENARIO = "panda-memory-person-leaves"


@pytest.fixture(scope="module")
def run() -> tuple[World, SimulationLog]:
    """1.5 s of a memory scenario; the world keeps the map its controller queried last."""
    clock = SimClock()
    world = build_world(SCENARIO, clock=clock)
    return world, run_world(world, clock, duration=1.5)


def _joints(log: SimulationLog):  # type: ignore[no-untyped-def]
    def q_at(k: int) -> dict[str, np.ndarray] | None:
        return {r: log.q[r][k] for r in log.robots} if 0 <= k < len(log.t) else None

    return q_at


def _map(memory: SceneMemory) -> tuple[np.ndarray, ...]:
    memory.obstacles()  # the fading of the hand-over
    return memory.state.copy(), memory.seen_at.copy(), memory.freed_at.copy()


def _replay(every: int = 30) -> tuple[World, MemoryReplay]:
    world = build_world(SCENARIO)
    feed = world.memories[0]
    return world, MemoryReplay(feed, [s for s in world.sensors if s.feed is feed], every)


def test_the_replayed_map_is_the_runs(run: tuple[World, SimulationLog]) -> None:
    ran, log = run
    world, replay = _replay()
    assert replay.advance(len(log.t) - 1, _joints(log), world.sight)
    ours, theirs = _map(replay.feed.memory), _map(ran.memories[0].memory)
    assert (theirs[0] == STATES["occupied"]).sum() > 100  # the camera saw the person
    for a, b in zip(ours, theirs, strict=True):
        np.testing.assert_array_equal(a, b)
    assert replay.feed.memory.stamp == ran.memories[0].memory.stamp


def test_seeking_back_and_forth_gives_the_same_maps(run: tuple[World, SimulationLog]) -> None:
    _, log = run
    q_at, T = _joints(log), len(log.t)
    ticks = [T - 1, T // 3, 5, T // 2, T - 1, 0]
    world, replay = _replay(every=4)  # many snapshots: thinning happens
    straight = {}
    for k in sorted(set(ticks)):  # forward only, one replay per target
        w, r = _replay()
        r.advance(k, q_at, w.sight)
        straight[k] = _map(r.feed.memory)
    for k in ticks:
        replay.advance(k, q_at, world.sight)
        for a, b in zip(_map(replay.feed.memory), straight[k], strict=True):
            np.testing.assert_array_equal(a, b)
    assert len(replay.snapshots) <= MAX_SNAPSHOTS


def test_the_replay_waits_for_joints_it_does_not_have(run: tuple[World, SimulationLog]) -> None:
    _, log = run
    q_at, T = _joints(log), len(log.t)
    world, replay = _replay()
    known = {k for k in range(T // 2)}
    replay.advance(T - 1, lambda k: q_at(k) if k in known else None, world.sight)
    assert replay.needs() < T // 2 + 40  # it stopped at the first frame it cannot render
    replay.advance(T - 1, q_at, world.sight)  # the joints arrived: it goes on
    w, straight = _replay()
    straight.advance(T - 1, q_at, w.sight)
    np.testing.assert_array_equal(replay.feed.memory.state, straight.feed.memory.state)


def test_voxel_centres_are_those_of_the_state(rng: np.random.Generator) -> None:
    state = rng.integers(0, 4, size=(7, 5, 6)).astype(np.uint8)
    origin, voxel = np.array([0.3, -1.0, 2.0]), 0.05
    for code in range(4):
        want = [origin + (np.array(ijk) + 0.5) * voxel for ijk in np.argwhere(state == code)]
        got = voxel_centres(state, origin, voxel, code, limit=10_000)
        np.testing.assert_allclose(got, np.reshape(want, (-1, 3)))
        few = voxel_centres(state, origin, voxel, code, limit=10)
        assert 0 < len(few) <= 10
        assert {tuple(p) for p in few.round(9)} <= {tuple(p) for p in got.round(9)}


def test_playback_draws_the_memory_by_state(
    viewer: Viewer, run: tuple[World, SimulationLog]
) -> None:
    _, log = run
    pb = Playback(viewer, log, build_world(SCENARIO))
    pb.show(len(log.t) - 1)
    memory = pb.sim.memories[0].feed.memory
    for state in ("occupied", "shadow", "free"):
        node = viewer.nodes[f"/memory/cell/{state}"]
        limit = MAX_VOXELS_SHOWN[state]
        want = voxel_centres(memory.state, memory.origin, memory.config.voxel, STATES[state], limit)
        assert 0 < len(want) <= limit
        np.testing.assert_allclose(node.points, want, atol=1e-6)
    assert viewer.nodes["/memory/cell/occupied"].visible
    assert not viewer.nodes["/memory/cell/free"].visible  # hidden until asked for


def test_a_snapshot_restores_the_map_and_refuses_another_grid(
    run: tuple[World, SimulationLog],
) -> None:
    memory = run[0].memories[0].memory
    snap = memory.snapshot()
    copy = SceneMemory(memory.origin, memory.origin + np.multiply(memory.shape, 0.03))
    copy.config = memory.config
    copy.restore(snap)
    for a, b in zip(_map(copy), _map(memory), strict=True):
        np.testing.assert_array_equal(a, b)
    copy.clear()
    assert copy.counts().unknown == copy.state.size and copy.stamp == -np.inf
    with pytest.raises(InputError, match="snapshot"):
        SceneMemory([0, 0, 0], [1, 1, 1]).restore(snap)


def test_the_live_view_draws_the_memory(viewer: Viewer) -> None:
    from reachwise.viz.live import LiveRun

    live = LiveRun(viewer, SCENARIO, duration=0.3, speed=0.0, fps=1e6)
    assert live.run() is not None
    assert len(viewer.nodes["/memory/cell/occupied"].points) > 0
    assert live.sim.memories[0].tick > 0
