"""Bounding boxes (P-V Table 1 steps 3–8): AABB, OBB/EOBB, separating axes, overlap box.

Truth for the separating-axis test and the overlap box is independent: points sampled
in the boxes, and linear programs (scipy) over the intersection polytope.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog
from scipy.spatial.transform import Rotation

from reachwise.errors import InputError
from reachwise.geometry.boxes import AABB, OBB, eobb, obb_overlap, overlap_box


def _pose(rng: np.random.Generator, spread: float = 1.0) -> np.ndarray:
    P = np.eye(4)
    P[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    P[:3, 3] = rng.uniform(-spread, spread, 3)
    return P


def _random_obb(rng: np.random.Generator, spread: float = 1.0, flat: float = 0.03) -> OBB:
    lo = rng.uniform(-0.5, 0.5, 3)
    hi = lo + rng.uniform(0.05, 1.0, 3) * (rng.random(3) > flat)  # some flat boxes
    return OBB(_pose(rng, spread), AABB(lo, hi))


def _constraints(box: OBB) -> tuple[np.ndarray, np.ndarray]:
    """World half-spaces A x <= c of an OBB."""
    R, t = box.pose[:3, :3], box.pose[:3, 3]
    A = np.vstack([R.T, -R.T])
    c = np.concatenate([box.box.hi + R.T @ t, -(box.box.lo + R.T @ t)])
    return A, c


def _lp_feasible(a: OBB, b: OBB, grow: float = 0.0) -> bool:
    Aa, ca = _constraints(a)
    Ab, cb = _constraints(b)
    res = linprog(
        np.zeros(3),
        A_ub=np.vstack([Aa, Ab]),
        b_ub=np.concatenate([ca, cb]) + grow,
        bounds=[(None, None)] * 3,
        method="highs",
    )
    return bool(res.status == 0)


def _sample_in(box: OBB, rng: np.random.Generator, n: int) -> np.ndarray:
    local = rng.uniform(box.box.lo, box.box.hi, size=(n, 3))
    return local @ box.pose[:3, :3].T + box.pose[:3, 3]


def test_aabb_of_points_is_tight_and_enlarged_by_delta(rng: np.random.Generator) -> None:
    p = rng.normal(size=(200, 3))
    box = AABB.of_points(p)
    assert box.contains(p).all()
    np.testing.assert_array_equal(box.lo, p.min(axis=0))
    np.testing.assert_array_equal(box.hi, p.max(axis=0))
    big = AABB.of_points(p, delta=0.1)
    np.testing.assert_allclose(big.lo, p.min(axis=0) - 0.1)
    np.testing.assert_allclose(big.hi, p.max(axis=0) + 0.1)
    np.testing.assert_allclose(big.center, box.center)
    np.testing.assert_allclose(big.half_extents, box.half_extents + 0.1)


def test_bad_boxes_raise() -> None:
    with pytest.raises(InputError, match="below lo"):
        AABB(np.ones(3), np.zeros(3))
    with pytest.raises(InputError, match="NaN"):
        AABB(np.array([np.nan, 0, 0]), np.ones(3))
    with pytest.raises(InputError, match=">= 0"):
        AABB(np.zeros(3), np.ones(3)).enlarged(-1.0)
    with pytest.raises(InputError, match="4x4"):
        OBB(np.eye(3), AABB(np.zeros(3), np.ones(3)))
    bad = np.eye(4)
    bad[0, 0] = 2.0
    with pytest.raises(InputError, match="rotation"):
        OBB(bad, AABB(np.zeros(3), np.ones(3)))


def test_obb_contains_its_vertices_and_mapped_points(rng: np.random.Generator) -> None:
    for _ in range(20):
        box = _random_obb(rng, flat=0.3)
        local = box.to_local(box.vertices())
        assert (local >= box.box.lo - 1e-12).all() and (local <= box.box.hi + 1e-12).all()
        solid = _random_obb(rng, flat=0.0)
        pts = _sample_in(solid, rng, 100)
        assert solid.contains(pts).all()
        np.testing.assert_allclose(box.center, box.vertices().mean(axis=0), atol=1e-12)


def test_eobb_is_the_enlarged_aabb_placed_by_the_pose(rng: np.random.Generator) -> None:
    p = rng.normal(size=(50, 3))
    P = _pose(rng)
    e = eobb(AABB.of_points(p), P, margin=0.2)
    world = p @ P[:3, :3].T + P[:3, 3]
    assert e.contains(world).all()
    np.testing.assert_allclose(e.half_extents, AABB.of_points(p).half_extents + 0.2)


def test_sat_agrees_with_linear_programming_and_samples(rng: np.random.Generator) -> None:
    n_overlap = n_apart = 0
    for _ in range(600):
        a = _random_obb(rng, spread=0.8)
        b = _random_obb(rng, spread=0.8)
        sat = obb_overlap(a, b)
        assert sat == obb_overlap(b, a)
        # sampled points of one box inside the other prove an overlap
        if a.contains(_sample_in(b, rng, 200)).any() or b.contains(_sample_in(a, rng, 200)).any():
            assert sat
        if _lp_feasible(a, b, grow=-1e-9):
            assert sat
            n_overlap += 1
        elif not _lp_feasible(a, b, grow=1e-9):
            assert not sat
            n_apart += 1
    assert n_overlap > 50 and n_apart > 50


def test_sat_with_parallel_edges() -> None:
    R = Rotation.from_euler("z", 30, degrees=True).as_matrix()
    base = AABB(np.zeros(3), np.ones(3))
    for gap, expect in [(-0.5, True), (0.0, True), (1e-6, False), (0.3, False)]:
        Pa = np.eye(4)
        Pa[:3, :3] = R
        Pb = Pa.copy()
        Pb[:3, 3] = R @ np.array([1.0 + gap, 0.0, 0.0])  # same axes, shifted along one
        assert obb_overlap(OBB(Pa, base), OBB(Pb, base)) is expect
        # edge to edge: shifted along a diagonal of two axes
        Pc = Pa.copy()
        Pc[:3, 3] = R @ np.array([1.0 + gap, 1.0 + gap, 0.2])
        assert obb_overlap(OBB(Pa, base), OBB(Pc, base)) is expect


def _lp_extent(a: OBB, b: OBB, axis: int, sign: float) -> float:
    """min (sign=1) or -max (sign=-1) of a's-frame coordinate ``axis`` over a ∩ b."""
    Aa, ca = _constraints(a)
    Ab, cb = _constraints(b)
    R, t = a.pose[:3, :3], a.pose[:3, 3]
    c = sign * R[:, axis]  # local coordinate = R[:, axis] · (x - t)
    res = linprog(
        c,
        A_ub=np.vstack([Aa, Ab]),
        b_ub=np.concatenate([ca, cb]),
        bounds=[(None, None)] * 3,
        method="highs",
    )
    assert res.status == 0
    return float(res.fun - sign * R[:, axis] @ t)


def test_overlap_box_is_the_tight_box_of_the_intersection(rng: np.random.Generator) -> None:
    checked = 0
    for _ in range(300):
        a = _random_obb(rng, spread=0.5, flat=0.0)
        b = _random_obb(rng, spread=0.5, flat=0.0)
        box = overlap_box(a, b)
        if not _lp_feasible(a, b, grow=-1e-7):
            if not _lp_feasible(a, b, grow=1e-9):
                assert box is None
            continue
        assert box is not None
        # every sampled point of a ∩ b is in the box (in a's frame)
        pts = _sample_in(a, rng, 4000)
        pts = pts[b.contains(pts)]
        assert box.contains(a.to_local(pts)).all()
        # and the box is tight: its faces are the extreme coordinates of a ∩ b
        for axis in range(3):
            lo = _lp_extent(a, b, axis, 1.0)
            hi = -_lp_extent(a, b, axis, -1.0)
            assert box.lo[axis] == pytest.approx(lo, abs=1e-7)
            assert box.hi[axis] == pytest.approx(hi, abs=1e-7)
        checked += 1
    assert checked > 50


def test_overlap_box_of_touching_boxes_is_not_lost() -> None:
    base = AABB(np.zeros(3), np.ones(3))
    Pb = np.eye(4)
    Pb[0, 3] = 1.0  # face to face
    box = overlap_box(OBB(np.eye(4), base), OBB(Pb, base))
    assert box is not None
    assert box.contains(np.array([[1.0, 0.5, 0.5]])).all()
    Pc = np.eye(4)
    Pc[:3, 3] = [1.0, 1.0, 1.0]  # corner to corner
    box = overlap_box(OBB(np.eye(4), base), OBB(Pc, base))
    assert box is not None and box.contains(np.ones((1, 3))).all()
    Pd = np.eye(4)
    Pd[0, 3] = 1.001
    assert overlap_box(OBB(np.eye(4), base), OBB(Pd, base)) is None
