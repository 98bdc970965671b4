"""Clearance terms of the design bodies: brute-force distances and finite differences."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from reachwise import load_robot
from reachwise.errors import InputError
from reachwise.kinematics.design_bodies import DesignBody
from reachwise.kinematics.robot import Convention, Robot
from reachwise.synthesis.clearance import (
    ENVIRONMENT,
    ClearanceModel,
    box_signed_distance,
    watched_pairs,
)
from reachwise.synthesis.problem import SynthesisProblem
from reachwise.tasks.task import Task
from reachwise.tasks.workspace import TunnelEnvelope, TunnelProfile

TUNNEL = TunnelEnvelope(TunnelProfile(width=8.5, height=7.2, arch_height=2.2))


def _with_bodies(robot: Robot, *extra: DesignBody, convention: Convention | None = None) -> Robot:
    design = dataclasses.replace(robot.design, bodies=robot.design.bodies + extra)
    out = dataclasses.replace(robot, design=design)
    if convention is not None:
        out = dataclasses.replace(out, convention=convention)
    return out


def _bracket() -> DesignBody:
    T = np.eye(4)
    T[:3, 3] = (-0.35, 0.0, 0.0)
    origin = tuple(tuple(float(v) for v in row) for row in T)
    return DesignBody("bracket", "link_0", "box", size=(0.5, 0.6, 0.7), origin=origin)


def _tilted_box() -> DesignBody:
    c, s = np.cos(0.4), np.sin(0.4)
    T = np.array([[c, -s, 0, 0.2], [s, c, 0, -0.3], [0, 0, 1, 0.5], [0, 0, 0, 1.0]])
    origin = tuple(tuple(float(v) for v in row) for row in T)
    return DesignBody("cradle_box", "link_6", "box", size=(0.3, 0.9, 0.25), origin=origin)


def _problem(robot: Robot, K: int = 4) -> SynthesisProblem:
    task = Task.from_arrays("t", np.zeros((K, 3)), dims=3)
    return SynthesisProblem(robot, task)


def _random_z(problem: SynthesisProblem, rng: np.random.Generator) -> np.ndarray:
    lo, hi = problem.bounds
    lo = np.where(np.isfinite(lo), lo, -1.0)
    hi = np.where(np.isfinite(hi), hi, 1.0)
    return lo + (hi - lo) * rng.uniform(0.05, 0.95, lo.size)


def _check_gradients(model: ClearanceModel, problem: SynthesisProblem, z: np.ndarray) -> None:
    t = model.terms(problem, z)
    p, nf = problem.p, problem.n_free_joints
    # a segment inside a box gives a penetration depth whose gradient is a subgradient
    # only (the documented limit); everywhere else the gradient is exact
    boxes = {b.name for b in model.robot.design.bodies if b.shape == "box"}
    on_box = np.array([a in boxes or b in boxes for a, b in model.labels])
    check = ~(on_box[None, :] & (t.distance <= 0.0))
    h = 1e-6
    for i in range(problem.size):
        dz = np.zeros_like(z)
        dz[i] = h
        fd = (model.terms(problem, z + dz).distance - model.terms(problem, z - dz).distance) / (
            2 * h
        )
        if i < p:
            g = t.grad_design[:, :, i]
        else:
            k, a = divmod(i - p, nf)
            g = np.zeros_like(fd)
            g[k] = t.grad_joints[k, :, a]
        tol = 1e-6 * max(1.0, float(np.abs(g).max()))
        assert np.allclose(g[check], fd[check], rtol=1e-6, atol=tol), (i, np.abs(g - fd).max())


def test_sb60_bodies_load_and_watch_non_adjacent_pairs() -> None:
    robot = load_robot("sb60")
    names = [b.name for b in robot.design.bodies]
    pairs = {(names[i], names[j]) for i, j in watched_pairs(robot)}
    # consecutive bodies (also through link_4 and link_6, which carry none) are adjacent
    assert ("boom", "feed_swing_bracket") not in pairs
    assert ("feed_swing_bracket", "rollover_arm") not in pairs
    assert ("rollover_arm", "feed") not in pairs
    assert ("boom", "feed") in pairs and ("boom_root", "feed") in pairs
    assert robot.design.clearance == 0.0  # bodies are kept clear only when asked


@pytest.mark.parametrize("convention", ["modified", "classic"])
def test_every_gradient_equals_central_differences(convention: Convention) -> None:
    rng = np.random.default_rng(3)
    robot = _with_bodies(load_robot("sb60"), _bracket(), convention=convention)
    problem = _problem(robot)
    model = ClearanceModel(robot, TUNNEL, 0.1)
    kinds = {b for _, b in model.labels}
    assert ENVIRONMENT in kinds and "bracket" in kinds
    for _ in range(3):
        _check_gradients(model, problem, _random_z(problem, rng))


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_clearance_gradients_hypothesis(seed: int) -> None:
    rng = np.random.default_rng(seed)
    robot = _with_bodies(load_robot("sb60"), _tilted_box())
    problem = _problem(robot, K=2)
    _check_gradients(ClearanceModel(robot, TUNNEL, 0.1), problem, _random_z(problem, rng))


def _capsule_samples(a: np.ndarray, b: np.ndarray, n: int = 400) -> np.ndarray:
    t = np.linspace(0.0, 1.0, n)
    return a[None] + t[:, None] * (b - a)[None]


def test_terms_equal_brute_force_distances() -> None:
    """Segment–segment and segment–box terms against dense sampling; environment terms
    against the envelope's distance sampled along each capsule's axis."""
    rng = np.random.default_rng(7)
    robot = _with_bodies(load_robot("sb60"), _tilted_box())
    problem = _problem(robot, K=3)
    model = ClearanceModel(robot, TUNNEL, 0.1)
    z = _random_z(problem, rng)
    t = model.terms(problem, z)
    pts, F, _ = model.anchor_points(problem, z)
    n_env = sum(len(p.env_ends) for p in model.parts)
    parts_pairs = model._part_pairs
    for k in range(problem.K):
        for i, (pa, pb) in enumerate(parts_pairs):
            A, B = model.parts[pa], model.parts[pb]
            sa = _capsule_samples(pts[k, A.ends[0]], pts[k, A.ends[1]], 2000)
            if B.kind == "segment":
                sb = _capsule_samples(pts[k, B.ends[0]], pts[k, B.ends[1]], 2000)
                d = np.linalg.norm(sa[:, None] - sb[None], axis=2).min() - A.radius - B.radius
                assert t.distance[k, n_env + i] == pytest.approx(d, abs=2e-3)
            else:
                W = F[k, B.frame] @ np.array(B.origin)
                local = (sa - W[:3, 3]) @ W[:3, :3]
                phi, _ = box_signed_distance(local[:, None, :], np.array([B.half]))
                assert t.distance[k, n_env + i] == pytest.approx(phi.min() - A.radius, abs=2e-3)
        # environment: the minimum over a capsule's axis is at an end (concave distance)
        j = 0
        for part in model.parts:
            m = len(part.env_ends)
            if part.kind == "segment":
                dense_pts = _capsule_samples(pts[k, part.env_ends[0]], pts[k, part.env_ends[1]])
            else:  # a grid through the box
                W = F[k, part.frame] @ np.array(part.origin)
                g = np.linspace(-1.0, 1.0, 9)
                grid = np.stack(np.meshgrid(g, g, g), -1).reshape(-1, 3) * np.array(part.half)
                dense_pts = grid @ W[:3, :3].T + W[:3, 3]
            dense = TUNNEL.signed_distance(dense_pts).min() - part.radius
            assert t.distance[k, j : j + m].min() == pytest.approx(dense, abs=1e-9)
            j += m


def test_distances_without_gradients_equal_the_terms() -> None:
    """The solver's trial merit (distances only) is the merit of the rows it keeps."""
    from reachwise.synthesis.clearance_rows import merit, stacked_rows
    from reachwise.synthesis.solvers import row_weights

    rng = np.random.default_rng(11)
    robot = _with_bodies(load_robot("sb60"), _tilted_box())
    problem = _problem(robot, K=5)
    model = ClearanceModel(robot, TUNNEL, 0.4)
    wx = row_weights(problem)
    on = 0
    for _ in range(4):
        z = _random_z(problem, rng)
        d = model.distances(problem, z)
        assert np.array_equal(d, model.terms(problem, z).distance)
        ev = problem.evaluate(z)
        rows = stacked_rows(problem, ev, wx, z, model)
        on += int(rows.active[:, 6:].sum())
        assert merit(problem, ev, wx, z, model) == pytest.approx(rows.cost, rel=1e-12)
    assert on > 0  # some clearance rows were on


def test_trial_merit_with_a_limit_decides_as_the_full_merit() -> None:
    """With a ``limit``, the trial merit skips the bodies' distances when the task rows
    alone exceed it: whether a trial is within the limit is decided exactly as by the
    full merit, a merit within it is the full merit to the bit, and a skipped one is
    the task rows' share, above the limit and at most the full merit. Limits are
    chosen on both sides of the task share and of the full merit, and between them
    (where the clearance rows alone push the trial over the limit)."""
    from reachwise.synthesis.clearance_rows import merit, stacked_rows
    from reachwise.synthesis.solvers import row_weights

    rng = np.random.default_rng(12)
    robot = _with_bodies(load_robot("sb60"), _tilted_box())
    problem = _problem(robot, K=5)
    model = ClearanceModel(robot, TUNNEL, 0.4)
    wx = row_weights(problem)
    skipped = between = 0
    for _ in range(6):
        z = _random_z(problem, rng)
        ev = problem.evaluate(z)
        full = merit(problem, ev, wx, z, model)
        task = stacked_rows(problem, ev, wx, z, None).cost
        assert task < full  # the clearance rows add to this merit
        for limit in (0.5 * task, task, 0.5 * (task + full), full, 2.0 * full):
            got = merit(problem, ev, wx, z, model, limit=limit)
            assert (got <= limit) == (full <= limit)
            if full <= limit or limit > task * (1 + 1e-9):
                assert got == full
            elif got != full:
                skipped += 1
                assert limit < got <= full
                assert got == pytest.approx(task, rel=1e-12)
            between += int(task * (1 + 1e-9) < limit < full)
    assert skipped > 0 and between > 0


def test_box_signed_distance_known_values() -> None:
    half = np.array([[1.0, 2.0, 3.0]])
    x = np.array([[[2.0, 0.0, 0.0]], [[0.5, 0.0, 0.0]], [[2.0, 3.0, 3.0]]])
    phi, g = box_signed_distance(x, half)
    assert phi[:, 0] == pytest.approx([1.0, -0.5, np.sqrt(2.0)])
    assert g[0, 0] == pytest.approx([1, 0, 0]) and g[1, 0] == pytest.approx([1, 0, 0])


def test_a_pair_of_two_boxes_is_rejected() -> None:
    robot = _with_bodies(load_robot("sb60"), _bracket(), _tilted_box())
    robot = dataclasses.replace(
        robot,
        design=dataclasses.replace(
            robot.design, bodies=(_bracket(), robot.design.bodies[1], _tilted_box())
        ),
    )
    with pytest.raises(InputError, match="capsule on one side"):
        watched_pairs(robot)


def test_contact_zone_shortens_only_the_environment_segment() -> None:
    robot = load_robot("sb60")
    model = ClearanceModel(robot, TUNNEL, 0.1)
    feed = next(p for p in model.parts if model.robot.design.bodies[p.body].name == "feed")
    assert feed.env_ends[0] == feed.ends[0] and feed.env_ends[1] != feed.ends[1]
    cut = np.array(model.anchors[feed.env_ends[1]].local)
    assert cut == pytest.approx([0.0, -0.1, 2.0])
