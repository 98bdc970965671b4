"""Which designs of a sweep are on the front (``synthesis.pareto.classify``), checked on
hand-made objective values against brute force."""

from __future__ import annotations

import numpy as np
import pytest

from reachwise import load_robot
from reachwise.kinematics.robot import Robot
from reachwise.synthesis.pareto import ParetoPoint, classify, dominated, extent

NAMES = ("gci", "size")  # maximize gci, minimize size
SENSES = np.array([1.0, -1.0])


@pytest.fixture(scope="module")
def robot() -> Robot:
    return load_robot("sb60")


def points(robot: Robot, rows: np.ndarray, reach: list[bool] | None = None) -> list[ParetoPoint]:
    """Designs with the given (gci, size) values, found in row order."""
    reach = reach or [True] * len(rows)
    return [
        ParetoPoint(
            index=i,
            weights={},
            robot=robot,
            design=np.zeros(0),
            q=np.zeros((1, robot.n)),
            reached=np.full(3, r),
            values={"gci": float(g), "size": float(s)},
            lci=np.zeros(1),
            bound_hits=(),
        )
        for i, ((g, s), r) in enumerate(zip(rows, reach, strict=True))
    ]


def eps_beats(v: np.ndarray, j: int, i: int, tol: float, scale: np.ndarray) -> bool:
    """Brute force: row ``j`` ε-dominates row ``i`` (not within ``tol`` in both, at
    least as good up to ``tol`` in both, better by more than ``tol`` in one)."""
    d = (v[j] - v[i]) * SENSES / scale
    return bool(not np.all(np.abs(d) <= tol) and np.all(d >= -tol) and np.any(d > tol))


def brute_force_front_extent(v: np.ndarray) -> np.ndarray:
    """The range of each column over the rows that no other row beats exactly (at
    least as good in both, better in one): the unit of the front's tolerance."""
    s = v * SENSES
    keep = [
        i for i in range(len(v))
        if not any(np.all(s[j] >= s[i]) and np.any(s[j] > s[i]) for j in range(len(v)))
    ]  # fmt: skip
    return extent(v[keep])


def test_the_unit_is_the_fronts_extent_not_the_sweeps(robot: Robot) -> None:
    """A far design that the front dominates (found late) does not widen the unit: two
    front designs 2 % of the front's extent apart stay two designs, where measured on
    the extent of every reaching design (five times wider) they would be one."""
    rows = np.array([
        [0.50, 0.50],  # the front: three designs over an extent of 0.1 × 0.1
        [0.502, 0.502],  # 2 % of the front's extent from the first
        [0.60, 0.60],
        [0.0, 1.0],  # far and dominated: the sweep's extent is 0.6 × 0.5
    ])  # fmt: skip
    marked = classify(points(robot, rows), NAMES, same=0.01)
    assert [p.dominated for p in marked] == [False, False, False, True]
    assert brute_force_front_extent(rows).tolist() == pytest.approx([0.1, 0.1])
    # the sweep's extent would make 1 the twin of 0
    assert np.all(np.abs(rows[1] - rows[0]) / extent(rows) <= 0.01)


def test_a_twin_of_a_dominated_design_is_judged_on_its_own(robot: Robot) -> None:
    """A chain seen on tunnel-87 (every one of 18 reaching designs was marked): 2 is the
    twin of the earlier 1, 1 is ε-dominated by 3, 3 is the twin of the earlier 0, 0 is
    ε-dominated by 2. Dropping a twin of a dropped design lost the whole cluster;
    3 ε-dominates every other design of it and stays."""
    rows = np.array([
        [0.495, 0.4905],  # 0: ε-dominated by 2 (1.3 % better gci, ≤ 1 % larger)
        [0.500, 0.5000],  # 1: ε-dominated by 3 (1.1 % smaller, same gci)
        [0.508, 0.5000],  # 2: twin of 1; ε-dominated by 3
        [0.500, 0.4890],  # 3: twin of 0; not dominated
        [0.0, 0.0],  # the front's two far ends: the extent is 1 in both
        [1.0, 1.0],
    ])  # fmt: skip
    scale = extent(rows)
    assert scale.tolist() == [1.0, 1.0]
    marked = classify(points(robot, rows), NAMES, same=0.01)
    assert [p.dominated for p in marked] == [True, True, True, False, False, False]
    assert [p.same_as for p in marked] == [None, None, None, None, None, None]
    # the old rule (twins of any earlier design, dominated or not) empties the cluster
    old = dominated(rows, SENSES, 0.01, scale)
    assert old[:4].all()


@pytest.mark.parametrize("seed", range(4))
def test_front_against_brute_force(robot: Robot, seed: int) -> None:
    """Near-ties everywhere (values on a grid of about the tolerance, with noise): the
    front is never empty, no front design ε-dominates another or is its twin, every
    design off it is beaten by a front design or is the twin of one, and designs that
    do not reach are off it."""
    rng = np.random.default_rng(seed)
    tol = 0.01
    for _ in range(200):
        m = int(rng.integers(2, 12))
        v = np.round(rng.uniform(0, 1, (m, 2)) / 0.008) * 0.008 + rng.normal(0, 0.002, (m, 2))
        reach = (rng.random(m) < 0.85).tolist()
        marked = classify(points(robot, v, reach), NAMES, same=tol)
        ok = np.flatnonzero(reach)
        if ok.size == 0:
            assert all(p.dominated for p in marked)
            continue
        scale = brute_force_front_extent(v[ok])
        front = [i for i in ok if not marked[i].dominated]
        assert front, "an empty front from reaching designs"
        assert all(marked[i].dominated for i in range(m) if not reach[i])
        for i in front:
            for j in front:
                if i != j:
                    assert not eps_beats(v, j, i, tol, scale)
                    assert not np.all(np.abs(v[j] - v[i]) / scale <= tol)
        for i in ok:
            if marked[i].dominated:
                twin = marked[i].same_as
                beaten = any(eps_beats(v, j, i, tol, scale) for j in ok if j != i)
                assert beaten or (twin is not None and twin in front and twin < i)
