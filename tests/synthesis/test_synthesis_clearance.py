"""Clearance in the synthesis: tunnel-87 with the sb60 bodies, checked by brute force.

The bodies are placed in each test by the robot's own forward kinematics and the DH
segments written out here, and their distances measured on densely sampled axes (5 mm
apart), independent of ``synthesis.clearance``.
"""

from __future__ import annotations

import numpy as np
import pytest

from reachwise import load_robot, load_task, synthesize
from reachwise.kinematics.robot import Robot
from reachwise.synthesis.clearance import watched_pairs
from reachwise.synthesis.synthesize import clearance_setup
from reachwise.tasks.task import Task
from reachwise.tasks.workspace import TunnelEnvelope

CLEARANCE = 0.1
PLANS = ("P01", "P02", "P03", "P04", "P05", "P06")


def _axes(robot: Robot, q: np.ndarray, env: bool = False) -> list[list[tuple]]:
    """Per body: its axis segments ``(start (K,3), end (K,3), radius)`` in world at the
    joint values ``q (K, n)``; ``env`` shortens a capsule by its contact zone."""
    F = np.asarray(robot.fk_all(q))
    out = []
    for b in robot.design.bodies:
        f = robot.link_names.index(b.link)
        segs = []
        if b.along:
            assert robot.convention == "modified"
            j = f - 1
            o, nxt = F[:, j, :3, 3], F[:, f, :3, 3]
            elbow = o + robot.dh[j, 0] * F[:, j, :3, 0]
            if "a" in b.along:
                segs.append((o, elbow, b.radius))
            if "d" in b.along:
                segs.append((elbow, nxt, b.radius))
        else:
            s, e = np.array(b.start), np.array(b.end)
            if env and b.contact:
                e = e - b.contact * (e - s) / np.linalg.norm(e - s)
            R, t = F[:, f, :3, :3], F[:, f, :3, 3]
            segs.append((R @ s + t, R @ e + t, b.radius))
        out.append(segs)
    return out


def _samples(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    n = max(2, int(np.ceil(np.linalg.norm(b - a) / 0.005)) + 1)
    t = np.linspace(0.0, 1.0, n)[:, None]
    return a[None] + t * (b - a)[None]


def brute_force_clearance(robot: Robot, q: np.ndarray, envelope: TunnelEnvelope) -> np.ndarray:
    """Per pose: the smallest distance of every watched pair and of every body (outside
    its contact zone) from the tunnel, by dense sampling."""
    bodies = _axes(robot, q)
    env_bodies = _axes(robot, q, env=True)
    K = q.shape[0]
    out = np.full(K, np.inf)
    for k in range(K):
        for i, j in watched_pairs(robot):
            for a0, a1, ra in bodies[i]:
                sa = _samples(a0[k], a1[k])
                for b0, b1, rb in bodies[j]:
                    sb = _samples(b0[k], b1[k])
                    d = np.sqrt(((sa[:, None] - sb[None]) ** 2).sum(-1)).min() - ra - rb
                    out[k] = min(out[k], d)
        for segs in env_bodies:
            for a0, a1, r in segs:
                d = envelope.signed_distance(_samples(a0[k], a1[k])).min() - r
                out[k] = min(out[k], d)
    return out


def _plans(task: Task, plans: tuple[str, ...]) -> Task:
    return task.subset([i for i, n in enumerate(task.names) if n.split("/")[0] in plans])


def test_reach_only_design_violates_the_clearance_at_five_or_more_poses() -> None:
    task = load_task("tunnel-87")
    assert task.envelope is not None
    res = synthesize(task, "sb60", runs=1, seed=0, clearance=0.0)
    assert res.reached.all() and res.unservable == ()
    d = brute_force_clearance(res.robot, res.q, task.envelope)
    assert int((d < CLEARANCE).sum()) >= 5


def test_poses_no_design_can_serve_are_named_before_the_solve() -> None:
    task = load_task("tunnel-87")
    assert task.envelope is not None
    robot = load_robot("sb60")
    model, kept, bad = clearance_setup(robot, task, task.envelope, CLEARANCE)
    assert model is not None and len(kept) == len(task) - len(bad)
    names = {u.name for u in bad}
    assert "P10/contour19" in names and "P01/lifter01" in names
    assert all("feed" in u.reason for u in bad)
    # the feed is fixed to the tool: a 6-D pose alone places it. Brute force over every
    # pose: the reported ones keep less than the clearance, the kept ones at least it.
    assert (task.dims == 6).all()
    f = robot.link_names.index("link_8")
    F0 = np.asarray(robot.fk_all(np.zeros(robot.n)))
    tool_in_8 = np.linalg.inv(F0[f]) @ F0[-1]
    feed = next(b for b in robot.design.bodies if b.name == "feed")
    s, e = np.array(feed.start), np.array(feed.end)
    e = e - feed.contact * (e - s) / np.linalg.norm(e - s)
    for k in range(len(task)):
        T8 = task.poses[k] @ np.linalg.inv(tool_in_8)
        axis = _samples(T8[:3, :3] @ s + T8[:3, 3], T8[:3, :3] @ e + T8[:3, 3])
        d = task.envelope.signed_distance(axis).min() - feed.radius
        assert (d < CLEARANCE) == (task.names[k] in names), task.names[k]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_clearance_constrained_synthesis_keeps_every_watched_pair(seed: int) -> None:
    """Plans P01–P06 of tunnel-87 (the poses no design can serve left out): every pose
    reached with every watched pair and every body at least 0.1 m clear, by brute force.
    The whole tunnel-87 figure is measured by ``reachwise bench synthesis``."""
    task = _plans(load_task("tunnel-87"), PLANS)
    assert task.envelope is not None
    res = synthesize(task, "sb60", runs=1, seed=seed, clearance=CLEARANCE)
    assert res.best.converged and res.reached.all()
    assert res.problem.K == len(task) - len(res.unservable) > 20
    d = brute_force_clearance(res.robot, res.q, task.envelope)
    assert (d >= CLEARANCE - 1e-9).all(), d.min()
    assert res.best.clearance is not None
    # the reported smallest clearance is the brute-force one (sampling only overestimates)
    assert np.all(res.best.clearance <= d + 1e-9)
    assert np.allclose(res.best.clearance, d, atol=2e-3)
