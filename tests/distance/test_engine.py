"""Every distance strategy equals brute force (thesis §3.1, P-V Table 1; issue 3).

Brute force (chunked numpy over every pair) is the independent truth. Cases cover
touching (d = 0) and interpenetrating clouds, duplicate points, planar and collinear
clouds, single points and sizes 1 … 20 000; ``no_risk`` is probed at margin ± 1e-6 m.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from reachwise import PointCloud
from reachwise.distance import NO_RISK, STRATEGIES, DistanceResult, PairQuery, closest_points
from reachwise.distance.brute import CHUNK_PAIRS, brute_min_pair
from reachwise.distance.index import INDICES
from reachwise.errors import CloudError, InputError

FAST = ("default", "thesis")
KINDS = (
    "random",
    "touching",
    "interpenetrating",
    "duplicates",
    "planar",
    "collinear",
    "single",
    "far",
)


def random_pose(rng: np.random.Generator, spread: float = 1.0) -> np.ndarray:
    P = np.eye(4)
    P[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    P[:3, 3] = rng.normal(size=3) * spread
    return P


def make_case(
    rng: np.random.Generator, kind: str, na: int, nb: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Clouds a, b (their frames) and poses; shaped by ``kind``."""
    scale_a = rng.uniform(0.05, 1.5, 3)
    scale_b = rng.uniform(0.05, 1.5, 3)
    A = rng.normal(size=(na, 3)) * scale_a
    B = rng.normal(size=(nb, 3)) * scale_b
    Pa, Pb = random_pose(rng), random_pose(rng)
    if kind == "touching":
        Pb = Pa.copy()  # same frame: b holds an exact copy of one point of a
        B[rng.integers(nb)] = A[rng.integers(na)]
    elif kind == "interpenetrating":
        Pb = Pa.copy()
        Pb[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    elif kind == "duplicates":
        A = A[rng.integers(0, na, na)]
        B = B[rng.integers(0, nb, nb)]
    elif kind == "planar":
        A[:, 2] = 0.0
        B[:, rng.integers(3)] = 0.3
    elif kind == "collinear":
        A[:, 1:] = 0.0
        B[:, :2] = 0.0
    elif kind == "single":
        A = A[:1]
    elif kind == "far":
        Pb[:3, 3] += rng.normal(size=3) * 20.0
    return A, B, Pa, Pb


def check_against(res: DistanceResult, ref: DistanceResult, margin: float, a, b, Pa, Pb) -> None:
    expect_no_risk = ref.distance > margin
    assert res.no_risk == expect_no_risk, (res, ref, margin)
    if res.no_risk:
        assert res is NO_RISK or (math.isinf(res.distance) and np.isnan(res.point_a).all())
        return
    assert abs(res.distance - ref.distance) <= 1e-9
    assert np.linalg.norm(res.point_a - res.point_b) == pytest.approx(
        res.distance, rel=1e-14, abs=1e-15
    )
    np.testing.assert_allclose(
        res.point_a, Pa[:3, :3] @ a[res.index_a] + Pa[:3, 3], rtol=0, atol=1e-12
    )
    np.testing.assert_allclose(
        res.point_b, Pb[:3, :3] @ b[res.index_b] + Pb[:3, 3], rtol=0, atol=1e-12
    )
    assert np.linalg.norm(res.direction) == pytest.approx(1.0, abs=1e-12)
    if res.distance > 0:
        np.testing.assert_allclose(
            res.direction, (res.point_a - res.point_b) / res.distance, atol=1e-12
        )


def run_case(A, B, Pa, Pb, rng: np.random.Generator) -> float:
    a, b = PointCloud(A), PointCloud(B)
    ref = closest_points(a, b, Pa, Pb, strategy="brute")
    assert not ref.no_risk
    d = ref.distance
    margins = [math.inf, d + 1e-6, float(rng.uniform(0.0, 2.0 * d + 0.1))]
    if d > 1e-6:
        margins.append(d - 1e-6)
    for margin in margins:
        ref_m = closest_points(a, b, Pa, Pb, margin, strategy="brute")
        check_against(ref_m, ref, margin, A, B, Pa, Pb)
        for s in FAST:
            check_against(
                closest_points(a, b, Pa, Pb, margin, strategy=s), ref, margin, A, B, Pa, Pb
            )
    return d


def test_all_strategies_equal_brute_force_on_1200_random_cases() -> None:
    rng = np.random.default_rng(9)
    zeros = 0
    for k in range(1200):
        kind = KINDS[k % len(KINDS)]
        na, nb = (int(x) for x in rng.integers(1, 400, 2))
        A, B, Pa, Pb = make_case(rng, kind, na, nb)
        d = run_case(A, B, Pa, Pb, rng)
        zeros += d == 0.0
    assert zeros >= 1200 // len(KINDS) - 5  # the touching cases really touch


@pytest.mark.parametrize(
    ("na", "nb", "kind"),
    [
        (20_000, 20_000, "random"),
        (20_000, 1, "single"),
        (1, 20_000, "random"),
        (3_000, 20_000, "interpenetrating"),
        (20_000, 2_000, "touching"),
        (5_000, 5_000, "planar"),
    ],
)
def test_large_clouds_equal_brute_force(na: int, nb: int, kind: str) -> None:
    rng = np.random.default_rng(na + 7 * nb)
    A, B, Pa, Pb = make_case(rng, kind, na, nb)
    if kind == "random":  # keep the pair apart: the thesis pipeline then selects a few points
        Pb[:3, 3] = Pa[:3, 3] + np.array([0.0, 0.0, 12.0])
    a, b = PointCloud(A), PointCloud(B)
    ref = closest_points(a, b, Pa, Pb, strategy="brute")
    d = ref.distance
    for margin in (d + 1e-6, max(d - 1e-6, 0.0)):
        for s in FAST:
            check_against(
                closest_points(a, b, Pa, Pb, margin, strategy=s), ref, margin, A, B, Pa, Pb
            )
    check_against(closest_points(a, b, Pa, Pb), ref, math.inf, A, B, Pa, Pb)


def test_brute_force_is_chunked_and_matches_a_direct_computation() -> None:
    rng = np.random.default_rng(1)
    wa = rng.normal(size=(CHUNK_PAIRS // 500 + 3, 3))
    wb = rng.normal(size=(700, 3)) + 3.0
    d2, i, j = brute_min_pair(wa, wb)
    full = ((wa[:, None, :] - wb[None, :, :]) ** 2).sum(-1)
    assert d2 == full.min()
    assert full[i, j] == full.min()


def test_touching_clouds_direction_points_from_b_centroid_to_a_centroid() -> None:
    A = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    B = np.array([[0.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [-2.0, 1.0, 0.0]])
    for s in STRATEGIES:
        r = closest_points(A, B, strategy=s)
        assert r.distance == 0.0 and not r.no_risk
        ca, cb = A.mean(axis=0), B.mean(axis=0)
        np.testing.assert_allclose(r.direction, (ca - cb) / np.linalg.norm(ca - cb), atol=1e-15)
        same = closest_points(A, A, strategy=s)  # centroids coincide too: +z
        np.testing.assert_array_equal(same.direction, [0.0, 0.0, 1.0])


def test_no_risk_result_says_so() -> None:
    A = np.zeros((1, 3))
    B = np.array([[0.0, 0.0, 2.0]])
    for s in STRATEGIES:
        r = closest_points(A, B, margin=1.0, strategy=s)
        assert r.no_risk and math.isinf(r.distance)
        assert np.isnan(r.point_a).all() and np.isnan(r.point_b).all()
        assert np.isnan(r.direction).all()
        assert r.index_a == -1 and r.index_b == -1
        at = closest_points(A, B, margin=2.0, strategy=s)  # exactly at the margin: at risk
        assert not at.no_risk and at.distance == 2.0


def _cloud(seed: int, n: int, offset: float) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, 3)) * rng.uniform(0.1, 1.0, 3) + offset


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    na=st.integers(1, 300),
    nb=st.integers(1, 300),
    offset=st.floats(-3.0, 3.0),
    strategy=st.sampled_from(STRATEGIES),
)
def test_symmetry(seed: int, na: int, nb: int, offset: float, strategy: str) -> None:
    rng = np.random.default_rng(seed)
    A, B = _cloud(seed, na, 0.0), _cloud(seed + 1, nb, offset)
    Pa, Pb = random_pose(rng), random_pose(rng)
    ab = closest_points(A, B, Pa, Pb, strategy=strategy)
    ba = closest_points(B, A, Pb, Pa, strategy=strategy)
    assert ab.distance == pytest.approx(ba.distance, abs=1e-12)
    # continuous random clouds have a unique closest pair
    np.testing.assert_allclose(ab.point_a, ba.point_b, atol=1e-12)
    np.testing.assert_allclose(ab.point_b, ba.point_a, atol=1e-12)
    np.testing.assert_allclose(ab.direction, -ba.direction, atol=1e-9)
    assert (ab.index_a, ab.index_b) == (ba.index_b, ba.index_a)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    na=st.integers(1, 300),
    nb=st.integers(1, 300),
    margin=st.floats(0.0, 5.0),
    strategy=st.sampled_from(STRATEGIES),
)
def test_invariance_under_rigid_motion(
    seed: int, na: int, nb: int, margin: float, strategy: str
) -> None:
    rng = np.random.default_rng(seed)
    A, B = _cloud(seed, na, 0.0), _cloud(seed + 1, nb, 1.0)
    Pa, Pb = random_pose(rng), random_pose(rng)
    G = random_pose(rng, spread=10.0)
    r = closest_points(A, B, Pa, Pb, margin, strategy=strategy)
    m = closest_points(A, B, G @ Pa, G @ Pb, margin, strategy=strategy)
    ref = closest_points(A, B, Pa, Pb, strategy="brute")
    if abs(ref.distance - margin) < 1e-9:
        return  # the no-risk boundary itself is not what this property is about
    assert r.no_risk == m.no_risk == (ref.distance > margin)
    if r.no_risk:
        return
    assert m.distance == pytest.approx(r.distance, abs=1e-9)
    np.testing.assert_allclose(m.point_a, G[:3, :3] @ r.point_a + G[:3, 3], atol=1e-9)
    np.testing.assert_allclose(m.point_b, G[:3, :3] @ r.point_b + G[:3, 3], atol=1e-9)
    np.testing.assert_allclose(m.direction, G[:3, :3] @ r.direction, atol=1e-7)


def test_pair_query_warm_start_stays_exact_along_a_trajectory() -> None:
    rng = np.random.default_rng(5)
    A = rng.normal(size=(800, 3)) * [0.5, 0.2, 0.1]
    B = rng.normal(size=(3000, 3)) * [2.0, 2.0, 0.05]
    a, b = PointCloud(A), PointCloud(B)
    pq = PairQuery(a, b, margin=0.6)
    R0 = Rotation.random(random_state=rng)
    for k in range(150):
        P = np.eye(4)
        P[:3, :3] = (Rotation.from_rotvec([0.0, 0.0, 0.01 * k]) * R0).as_matrix()
        P[:3, 3] = [0.01 * k - 0.7, 0.0, 0.3 + 0.4 * math.sin(0.05 * k)]
        ref = closest_points(a, b, P, None, 0.6, strategy="brute")
        got = pq(P)
        assert got.no_risk == ref.no_risk
        if not ref.no_risk:
            assert got.distance == pytest.approx(ref.distance, abs=1e-12)
    for s in ("thesis", "brute"):
        q = PairQuery(a, b, margin=0.6, strategy=s)
        assert q(P).no_risk == ref.no_risk


def test_point_cloud_keeps_its_index() -> None:
    rng = np.random.default_rng(2)
    a = PointCloud(rng.normal(size=(100, 3)))
    b = PointCloud(rng.normal(size=(100, 3)) + 5)
    closest_points(a, b)
    index = INDICES.peek(a)
    assert index is not None
    builds = INDICES.builds
    closest_points(a, b, strategy="thesis")
    closest_points(a, b)
    assert INDICES.builds == builds  # nothing rebuilt
    assert INDICES.peek(a) is index


def test_read_only_and_non_contiguous_poses_are_accepted() -> None:
    rng = np.random.default_rng(3)
    A, B = rng.normal(size=(50, 3)), rng.normal(size=(60, 3)) + 2
    P = random_pose(rng)
    ref = closest_points(A, B, P, None, strategy="brute")
    ro = P.copy()
    ro.setflags(write=False)
    fortran = np.asfortranarray(P)
    for pose in (ro, fortran, P.tolist()):
        assert closest_points(A, B, pose).distance == pytest.approx(ref.distance, abs=1e-12)


def test_nearly_orthonormal_rotation_is_snapped_alike_by_all_strategies() -> None:
    rng = np.random.default_rng(4)
    A, B = rng.normal(size=(80, 3)), rng.normal(size=(90, 3)) + 1.5
    P = random_pose(rng)
    P[:3, :3] *= 1.0 + 3e-7  # e.g. a pose written with 6-7 significant digits
    ref = closest_points(A, B, P, None, strategy="brute")
    for s in FAST:
        assert closest_points(A, B, P, None, strategy=s).distance == pytest.approx(
            ref.distance, abs=1e-12
        )


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_bad_inputs_raise_clear_errors(strategy: str) -> None:
    A = np.zeros((3, 3))
    B = np.ones((4, 3))
    with pytest.raises(InputError, match=r"pose_a.*4x4"):
        closest_points(A, B, np.eye(3), strategy=strategy)
    nan = np.eye(4)
    nan[0, 3] = np.nan
    with pytest.raises(InputError, match=r"pose_b.*NaN"):
        closest_points(A, B, None, nan, strategy=strategy)
    skew = np.eye(4)
    skew[0, 1] = 0.1
    with pytest.raises(InputError, match=r"pose_a: rotation: not orthonormal"):
        closest_points(A, B, skew, strategy=strategy)
    mirror = np.diag([1.0, 1.0, -1.0, 1.0])
    with pytest.raises(InputError, match=r"proper rotation"):
        closest_points(A, B, mirror, strategy=strategy)
    row = np.eye(4)
    row[3, 0] = 1.0
    with pytest.raises(InputError, match=r"bottom row"):
        closest_points(A, B, row, strategy=strategy)
    with pytest.raises(InputError, match=r"margin"):
        closest_points(A, B, margin=-1.0, strategy=strategy)
    with pytest.raises(InputError, match=r"margin"):
        closest_points(A, B, margin=float("nan"), strategy=strategy)
    with pytest.raises(CloudError, match=r"not finite"):
        closest_points(np.array([[0.0, np.nan, 0.0]]), B, strategy=strategy)
    with pytest.raises(CloudError, match=r"empty"):
        closest_points(np.zeros((0, 3)), B, strategy=strategy)
    with pytest.raises(CloudError, match=r"shape"):
        closest_points(np.zeros((4, 2)), B, strategy=strategy)


def test_unknown_strategy() -> None:
    with pytest.raises(InputError, match=r"unknown strategy 'octree'"):
        closest_points(np.zeros((1, 3)), np.ones((1, 3)), strategy="octree")
    with pytest.raises(InputError, match=r"unknown strategy"):
        PairQuery(np.zeros((1, 3)), np.ones((1, 3)), strategy="fast")


def test_kernels_never_compile_during_a_query() -> None:
    from reachwise.distance import _build as B
    from reachwise.distance import _kernels as K

    kernels = {"dual_tree_query": K.dual_tree_query, "build_tree": B.build_tree}
    before = {name: len(k.signatures) for name, k in kernels.items()}
    rng = np.random.default_rng(6)
    closest_points(rng.normal(size=(30, 3)), rng.normal(size=(40, 3)), random_pose(rng))
    after = {name: len(k.signatures) for name, k in kernels.items()}
    assert before == after == {"dual_tree_query": 1, "build_tree": 1}


def test_the_query_kernel_refuses_output_arrays_it_would_overrun() -> None:
    """The kernel writes without bounds checks: too short an output must be refused,
    not written past (it corrupted the heap before the check)."""
    from reachwise.distance import _kernels as K
    from reachwise.distance.index import build_index

    rng = np.random.default_rng(7)
    ta, tb = build_index(rng.normal(size=(20, 3))), build_index(rng.normal(size=(30, 3)))
    args = (
        ta.points, ta.boxes, ta.info, ta.perm, ta.centroid,
        tb.points, tb.boxes, tb.info, tb.perm, tb.centroid,
        np.eye(4), np.eye(4), math.inf, -1, -1, False,
    )  # fmt: skip
    for out, idx in ((np.empty(10), np.empty(2, np.int64)), (np.empty(9), np.empty(4, np.int64))):
        with pytest.raises(ValueError, match="out needs 10 entries and out_idx 4"):
            K.dual_tree_query(*args, out, idx)
    idx = np.empty(4, np.int64)
    assert K.dual_tree_query(*args, np.empty(10), idx) == 0 and idx.min() >= 0
