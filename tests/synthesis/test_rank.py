"""Ranking by GCI, KCI, their mean (P-II Table 2) and further measures."""

from __future__ import annotations

import math

import numpy as np
import pytest

from reachwise import load_robot
from reachwise.errors import InputError
from reachwise.kinematics.indices import gci, kci, lci
from reachwise.synthesis.rank import (
    RANK_KEYS,
    SAME_FIGURE,
    Candidate,
    Measures,
    best_first,
    best_run_index,
    first_best,
    link_length,
    measures,
    rank,
)


def _m(
    g: float, k: float, w: float = 1.0, length: float = 5.0, p: int = 1,
    size: float = math.nan, limits: float = math.nan, bounds: float = math.nan,
    clearance: float = math.nan,
) -> Measures:  # fmt: skip
    return Measures(g, k, 0.5 * (g + k), w, length, p, size, limits, bounds, clearance)


def test_measures_match_the_indices_of_p2_eq_38_39(rng: np.random.Generator) -> None:
    robot = load_robot("p2-man2")
    Q = rng.uniform(robot.lower, np.minimum(robot.upper, 3.0), (30, robot.n))
    m = measures(robot, Q)
    lc = lci(robot, Q)
    assert m.gci == pytest.approx(gci(lc), rel=1e-12)
    assert m.kci == pytest.approx(kci(lc), rel=1e-12)
    assert m.mean == pytest.approx(0.5 * (m.gci + m.kci))
    assert 0 <= m.kci <= m.gci <= 1
    assert m.prismatic == 2
    assert m.length == pytest.approx(link_length(robot))
    assert m.manipulability > 0


def test_table_2_mean_column_is_the_mean_of_gci_and_kci() -> None:
    # P-II Table 2, configuration 1 and 2: mean = (GCI + KCI) / 2 to the printed digits
    for g, k, mean in [(0.1043, 0.0744, 0.0894), (0.1158, 0.0858, 0.1008),
                       (0.0741, 0.0058, 0.0400)]:  # fmt: skip
        assert _m(g, k).mean == pytest.approx(mean, abs=6e-5)


def test_link_length_sums_a_and_d() -> None:
    robot = load_robot("p2-man1")
    assert link_length(robot) == pytest.approx(sum(abs(j.a) + abs(j.d) for j in robot.joints))


def test_rank_by_each_key_and_infeasible_unranked() -> None:
    cands = [
        Candidate("a", 10, 10, _m(0.10, 0.07, 5.0, 9.0, 2, 3.0, 0.2, 1.0, clearance=0.3)),
        Candidate("b", 10, 10, _m(0.12, 0.05, 1.0, 4.0, 0, 2.0, 0.3, 0.0, clearance=0.1)),
        Candidate("c", 10, 10, _m(0.08, 0.08, 9.0, 6.0, 1, 4.0, 0.1, 2.0, clearance=0.2)),
        Candidate("x", 9, 10, _m(0.50, 0.40)),  # misses a point: never ranked
        Candidate("y", 3, 10, None),
    ]
    order = {
        "gci": ["b", "a", "c"],
        "kci": ["c", "a", "b"],
        "mean": ["b", "a", "c"],  # a's and b's mean 0.085 differ by rounding: GCI decides
        "manipulability": ["c", "a", "b"],
        "length": ["b", "c", "a"],
        "prismatic": ["b", "c", "a"],
        "size": ["b", "a", "c"],
        "limits": ["c", "a", "b"],
        "bounds": ["b", "a", "c"],
        "clearance": ["a", "c", "b"],
    }
    assert set(order) == set(RANK_KEYS)
    for key, want in order.items():
        rows = rank(cands, key)
        assert [r.candidate.name for r in rows if r.rank is not None] == want, key
        assert [r.rank for r in rows] == [1, 2, 3, None, None]
        assert [r.candidate.name for r in rows[3:]] == ["x", "y"]
        assert not rows[3].candidate.feasible


def test_ties_are_broken_deterministically() -> None:
    same = _m(0.1, 0.05)
    cands = [Candidate(n, 5, 5, same) for n in ("zeta", "alpha", "mid")]
    a = [r.candidate.name for r in rank(cands, "gci")]
    b = [r.candidate.name for r in rank(list(reversed(cands)), "gci")]
    assert a == b == ["alpha", "mid", "zeta"]
    # equal key, better mean wins
    c = [Candidate("p", 5, 5, _m(0.1, 0.01)), Candidate("q", 5, 5, _m(0.1, 0.09))]
    assert [r.candidate.name for r in rank(c, "gci")] == ["q", "p"]


def _exact(g: float, k: float, mean: float, length: float = 5.0) -> Measures:
    return Measures(g, k, mean, 1.0, length, 1)


def test_figures_within_rounding_of_each_other_do_not_order_topologies() -> None:
    """Two topologies whose key figure differs by rounding noise (1e-12 relative) are
    ordered by the next figure, and with every figure equal within noise by the name,
    as a topology's best run is chosen; a real difference (1e-6) still decides."""
    for sign in (1.0, -1.0):
        noisy = 0.05 * (1 + sign * 1e-12)
        better_gci = Candidate("b", 5, 5, _exact(0.08, 0.02, 0.05))
        worse_gci = Candidate("a", 5, 5, _exact(0.07, 0.03, noisy))
        for cands in ([better_gci, worse_gci], [worse_gci, better_gci]):
            assert [r.candidate.name for r in rank(cands, "mean")] == ["b", "a"]
        # every figure equal up to noise: the name
        z = Candidate("z", 5, 5, _exact(0.08 * (1 - sign * 1e-12), 0.02, noisy, 5.0 + 1e-11))
        for cands in ([better_gci, z], [z, better_gci]):
            assert [r.candidate.name for r in rank(cands, "mean")] == ["b", "z"]
    far = Candidate("a", 5, 5, _exact(0.07, 0.03, 0.05 * (1 + 1e-6)))
    assert [r.candidate.name for r in rank([better_gci, far], "mean")] == ["a", "b"]
    # lower-is-better keys likewise: a length 1e-12 shorter does not decide
    short = Candidate("s", 5, 5, _exact(0.07, 0.03, 0.05, 6.0 * (1 - 1e-12)))
    long = Candidate("l", 5, 5, _exact(0.08, 0.02, 0.05, 6.0))
    assert [r.candidate.name for r in rank([short, long], "length")] == ["l", "s"]


def test_best_first_is_the_exact_sort_without_near_ties(rng: np.random.Generator) -> None:
    """Figures at least 1e-6 apart (or equal) order as the sorted tuples, then the index;
    each step is first_best of the rest."""
    for _ in range(20):
        figs = [tuple(float(v) for v in row) for row in rng.integers(0, 3, (12, 3)) * 1e-3 + 1]
        want = sorted(range(len(figs)), key=lambda i: (figs[i], i))
        assert best_first(figs) == want
        assert first_best(figs) == want[0]
    assert best_first([]) == []
    assert best_first([(math.nan,), (math.inf,), (1.0,)]) == [2, 0, 1]  # NaN: the worst
    assert 1e-12 < SAME_FIGURE < 1e-6


def test_rank_errors() -> None:
    with pytest.raises(InputError, match="key"):
        rank([], "speed")
    with pytest.raises(InputError, match="unique"):
        rank([Candidate("a", 1, 1, _m(0.1, 0.1))] * 2)
    with pytest.raises(InputError, match="key"):
        _m(0.1, 0.1).value("nope")


def test_an_objective_not_measured_ranks_last() -> None:
    cands = [Candidate("m", 5, 5, _m(0.1, 0.05, size=3.0)), Candidate("n", 5, 5, _m(0.2, 0.1))]
    assert [r.candidate.name for r in rank(cands, "size")] == ["m", "n"]
    assert [r.candidate.name for r in rank(cands, "gci")] == ["n", "m"]


def test_best_run_is_the_rule_of_synthesize() -> None:
    assert best_run_index([5, 7, 7], [0.1, 0.3, 0.2]) == 2
    # with a design objective: most reached first, then the objective, then e_obj
    assert best_run_index([7, 7, 6], [0.1, 0.3, 0.0], [0.5, -0.2, -9.0]) == 1
    assert best_run_index([7, 7], [0.3, 0.1], [0.0, 0.0]) == 1
    assert best_run_index([7, 7], [0.2, 0.2]) == 0
    assert best_run_index([1], [math.inf]) == 0
    with pytest.raises(InputError):
        best_run_index([], [])


def test_runs_reaching_every_point_are_chosen_by_conditioning_not_by_rounding() -> None:
    # two converged runs whose pose errors are rounding noise: the higher GCI wins, in
    # either order of their errors (the e_obj rule flips with them)
    cond = [(0.05, 0.01), (0.06, 0.005)]
    assert best_run_index([7, 7], [2.8e-14, 2.9e-14], None, cond, 7) == 1
    assert best_run_index([7, 7], [2.9e-14, 2.8e-14], None, cond, 7) == 1
    assert best_run_index([7, 7], [2.8e-14, 2.9e-14]) == 0  # without conditioning: e_obj
    # GCI equal up to rounding: KCI decides; both equal: the first run
    same = [(0.05, 0.01), (0.05 * (1 + 1e-12), 0.02)]
    assert best_run_index([7, 7], [1e-13, 2e-13], None, same, 7) == 1
    assert best_run_index([7, 7], [2e-13, 1e-13], None, [(0.05, 0.01)] * 2, 7) == 0
    # a run short of a point never wins on conditioning; short runs compare pose errors
    assert best_run_index([6, 7], [0.0, 1e-13], None, [(0.9, 0.9), (0.01, 0.001)], 7) == 1
    assert best_run_index([6, 6], [0.3, 0.1], None, [(0.9, 0.9), (0.01, 0.01)], 7) == 1
    # a design objective still comes first; a figure that is not finite is the worst
    assert best_run_index([7, 7], [1e-13] * 2, [0.5, -0.2], [(0.9, 0.9), (0.01, 0.01)], 7) == 1
    assert best_run_index([7, 7], [0.0, 0.0], None, [(math.nan, 0.1), (0.01, 0.01)], 7) == 1


def test_first_best_compares_figure_by_figure_with_rounding_equal() -> None:
    assert first_best([(1.0, 5.0), (1.0 + 1e-12, 4.0)]) == 1  # first figures equal
    assert first_best([(1.0, 5.0), (1.0 + 1e-6, 4.0)]) == 0  # a real difference decides
    assert first_best([(2.0, 1.0), (2.0, 1.0)]) == 0  # a tie: the lowest index
    assert first_best([(math.inf,), (3.0,)]) == 1
    with pytest.raises(InputError):
        first_best([])


def test_a_run_with_an_undefined_lci_is_the_worst_not_an_error() -> None:
    """``result_of``'s conditioning of a run: a NaN LCI (a Jacobian that is not finite)
    ranks the run last among runs reaching every point instead of raising."""
    from types import SimpleNamespace

    from reachwise.synthesis.synthesize import _conditioning

    good = SimpleNamespace(n_reached=3, lci_final=np.array([0.2, 0.1, 0.3]))
    bad = SimpleNamespace(n_reached=3, lci_final=np.array([0.2, np.nan, 0.3]))
    short = SimpleNamespace(n_reached=2, lci_final=np.array([0.2, 0.1, 0.3]))
    assert _conditioning(good, 3) == pytest.approx((0.2, 0.1))  # type: ignore[arg-type]
    assert _conditioning(bad, 3) == (-math.inf, -math.inf)  # type: ignore[arg-type]
    assert _conditioning(short, 3) == (-math.inf, -math.inf)  # type: ignore[arg-type]
    cond = [_conditioning(r, 3) for r in (bad, good)]  # type: ignore[arg-type]
    assert best_run_index([3, 3], [1e-13, 1e-13], None, cond, 3) == 1
