"""The pair rules take cloud distances as conservative by the clouds' resolution: a pair
counts as close when its cloud distance is within the margin plus both clouds'
resolutions, and a structurally close pair is excluded or gets a margin of its own by
the same measure. Truth: brute-force nearest distances (cKDTree) between the placed
clouds."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

import reachwise
from reachwise.distance.self_pairs import (
    ALWAYS_FRACTION,
    random_configurations,
    self_collision_pairs,
)
from reachwise.geometry.cloud import PointCloud
from tests._real_arms import ARMS, arm_path, needs_erd

pytestmark = needs_erd
MARGIN, RES, SAMPLES = 0.04, 0.01, 200


def test_a_pair_is_never_close_only_beyond_margin_plus_both_resolutions() -> None:
    robot = reachwise.load_robot(arm_path("ur5"), tip=ARMS["ur5"][1])
    sampled = reachwise.link_clouds(robot, points=300)
    rated = {
        k: PointCloud(c.points, frame=c.frame, name=c.name, resolution=RES)
        for k, c in sampled.items()
    }
    plain = self_collision_pairs(robot, sampled, MARGIN, samples=SAMPLES, local_search=False)
    sure = self_collision_pairs(robot, rated, MARGIN, samples=SAMPLES, local_search=False)
    F = robot.fk_all(random_configurations(robot, SAMPLES, 0))

    def closest(a: str, b: str) -> float:
        ia, ib = robot.link_index(a), robot.link_index(b)
        best = np.inf
        for f in F:
            pa = sampled[a].points @ f[ia, :3, :3].T + f[ia, :3, 3]
            pb = sampled[b].points @ f[ib, :3, :3].T + f[ib, :3, 3]
            best = min(best, float(cKDTree(pa).query(pb)[0].min()))
        return best

    rules = {(p.a, p.b): p.rule for p in plain.pairs}
    moved = 0
    for p in sure.pairs:
        if p.rule == "never":
            assert closest(p.a, p.b) > MARGIN + 2 * RES, (p.a, p.b)
        elif rules[(p.a, p.b)] == "never":  # close only once the resolutions count
            d = closest(p.a, p.b)
            assert MARGIN < d <= MARGIN + 2 * RES, (p.a, p.b, d)
            moved += 1
    assert moved > 0  # the resolutions changed a rule
    assert sure.margin == plain.margin == MARGIN  # the margin stays the surfaces' margin


def test_structurally_close_pairs_are_excluded_only_when_their_clouds_stay_apart(
    tmp_path: Path,
) -> None:
    """The Panda at a 2.5 cm margin with its default clouds (1 cm coverage: 4.5 cm
    between the clouds): forearm and flange (panda_link5-panda_link7) are within it in
    nearly every configuration, but their clouds come within their resolutions (they
    touch when joint 6 folds): watched with a margin of their own. Every pair within the
    margin in 95 % of the samples is checked by k-d tree on the same samples: excluded
    as ``always`` when its clouds stay more than both resolutions apart everywhere (or,
    its clouds within their resolutions in 95 % of the samples, too coarse for it, when
    its cloud distance is within the margin in 95 %); else watched with its own margin:
    the 5 % quantile less the resolutions, at least 0, or for a pair too close for its
    clouds the margin less the resolutions (the margin between the clouds); within it in
    less than 95 %. The own margins survive the pairs file."""
    from reachwise.io.pairs_file import load_pairs, save_pairs

    robot = reachwise.load_robot(arm_path("panda"), tip=ARMS["panda"][1])
    clouds = reachwise.link_clouds(robot)
    margin, n = 0.025, 1000
    found = self_collision_pairs(robot, clouds, margin, samples=n, local_search=False)
    Q = random_configurations(robot, n, 0)  # the samples the rules saw
    F = robot.fk_all(Q)

    def kd(a: str, b: str) -> np.ndarray:
        ia, ib = robot.link_index(a), robot.link_index(b)
        out = np.empty(n)
        for s, f in enumerate(F):
            pa = clouds[a].points @ f[ia, :3, :3].T + f[ia, :3, 3]
            pb = clouds[b].points @ f[ib, :3, :3].T + f[ib, :3, 3]
            out[s] = cKDTree(pb).query(pa)[0].min()
        return out

    own = {(p.a, p.b): p for p in found.pairs if p.margin is not None}
    assert ("panda_link5", "panda_link7") in own
    for p in [*found.always, *own.values()]:
        cov = clouds[p.a].resolution + clouds[p.b].resolution
        d = kd(p.a, p.b)
        assert np.mean(d <= margin + cov + 1e-9) >= ALWAYS_FRACTION, (p.a, p.b)
        coarse = np.mean(d <= cov) >= ALWAYS_FRACTION  # beyond what the clouds can tell
        if p.rule == "always":
            assert d.min() > cov or (coarse and np.mean(d <= margin) >= ALWAYS_FRACTION)
            continue
        assert d.min() <= cov and p.margin is not None
        q5 = np.sort(d)[int((1 - ALWAYS_FRACTION) * n)]
        want = margin - cov if coarse else max(q5 - cov, 0.0)
        assert p.margin == pytest.approx(want, abs=1e-9), (p.a, p.b)
        assert np.mean(d <= p.margin + cov) < ALWAYS_FRACTION, (p.a, p.b)
    assert (
        found.margins[("panda_link5", "panda_link7")] == own[("panda_link5", "panda_link7")].margin
    )
    back, _ = load_pairs(save_pairs(found, tmp_path / "pairs.yaml"))
    assert back.margins == found.margins
