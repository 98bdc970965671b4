"""The real-arm scenarios of issue 16 (example-robot-data's Panda, its collision meshes,
automatic self-collision pairs): the conventional controller collides and says when
and with which pair; with avoidance every goal is reached, at least 2 cm from
everything watched at every tick (a structurally close pair watched with a margin of
its own under 4 cm between the clouds: at least half its margin, the velocity damper's
stop distance), no solids overlapping, limits and speed bounds held."""

from __future__ import annotations

import numpy as np
import pytest

import reachwise
from reachwise.sim.log import SimulationLog
from tests._real_arms import needs_erd

pytestmark = needs_erd


def _avoids(log: SimulationLog) -> None:
    assert log.all_goals_reached, [g for g in log.goals if g.reached_at is None]
    floor = np.minimum(0.02, 0.5 * log.margins)  # the damper's stop distance, at most 2 cm
    closest = log.signed.min(axis=0)
    assert np.all(closest >= floor), [
        (p, float(d), float(m)) for p, d, m in zip(log.pairs, closest, log.margins, strict=True)
        if d < 0.02
    ]  # fmt: skip
    assert log.first_collision is None
    assert all(log.limits_held().values()) and all(log.speeds_held().values())


def _collides(log: SimulationLog, pair: str) -> None:
    assert log.first_collision is not None and log.first_collision_pair is not None
    assert pair in log.first_collision_pair, log.first_collision_pair
    said = [e for e in log.events if e.kind == "collision"]
    assert said and said[0].t == pytest.approx(log.first_collision)
    assert log.first_collision_pair.split("|")[0] in said[0].text


@pytest.fixture(scope="module")
def shelf() -> tuple[SimulationLog, SimulationLog]:
    return reachwise.simulate("panda-shelf"), reachwise.simulate("panda-shelf", avoidance=False)


def test_panda_shelf_avoidance_reaches_both_goals(shelf: tuple[SimulationLog, ...]) -> None:
    _avoids(shelf[0])
    assert {p.split("|")[1] for p in shelf[0].pairs if "shelf" in p} == {"shelf"}
    assert sum("shelf" not in p for p in shelf[0].pairs) >= 5  # automatic self pairs


def test_panda_shelf_margins_are_conservative_by_the_clouds_resolution(
    shelf: tuple[SimulationLog, ...],
) -> None:
    """Every link cloud covers its shapes within 1 cm: the controller's margin of a link
    against the scan is 5 cm + 1 cm, of a self pair 2.5 cm + 2 cm; the forearm-flange
    pair (structurally close, its clouds within their resolutions when joint 6 folds)
    is watched with a smaller margin of its own, at least its 2 cm of resolutions."""
    log = shelf[0]
    margin = dict(zip(log.pairs, log.margins, strict=True))
    for p, m in margin.items():
        if "shelf" in p:
            assert m == pytest.approx(0.06), p
        elif p != "arm/panda_link5|arm/panda_link7":
            assert m == pytest.approx(0.045), p
    assert 0.02 <= margin["arm/panda_link5|arm/panda_link7"] < 0.045


def test_panda_shelf_baseline_hits_the_shelf(shelf: tuple[SimulationLog, ...]) -> None:
    _collides(shelf[1], "shelf")
    assert 0.5 < shelf[1].first_collision < 5.0


def test_panda_self_collision_baseline_folds_the_wrist_avoidance_does_not() -> None:
    base = reachwise.simulate("panda-self-collision", avoidance=False)
    _collides(base, "arm/panda_link5|arm/panda_link7")
    assert 1.0 < base.first_collision < 4.0
    avoid = reachwise.simulate("panda-self-collision")
    _avoids(avoid)
    assert all(p.count("arm/") == 2 for p in avoid.pairs)  # self pairs only, picked for us


def test_ur5_box_names_the_pairs_inside_their_margins_at_start_and_reaches_both_goals() -> None:
    """The UR5 at a 2 cm self margin: the wrist pair within it nearly everywhere is
    excluded as 'always' or watched with a smaller margin of its own; every watched
    pair that starts inside its margin is named at the start (pair, distance, margin)
    and none other; the run never stalls, reaches both goals and touches nothing."""
    log = reachwise.simulate("ur5-box")
    inside = {e.text.split()[0]: e for e in log.events if e.kind == "inside margin"}
    starts = {p for k, p in enumerate(log.pairs) if log.distance[0, k] < log.margins[k]}
    assert set(inside) == starts
    for k, p in enumerate(log.pairs):
        if p in inside:
            text = inside[p].text
            assert f"{log.distance[0, k]:.4f} m apart" in text and inside[p].t == 0.0
            assert f"{log.margins[k]:g} m margin" in text
    margin = dict(zip(log.pairs, log.margins, strict=True))
    wrist = "arm/wrist_1_link|arm/wrist_3_link"  # within 2 cm nearly everywhere
    assert wrist not in margin or margin[wrist] < 0.04  # excluded, or its own margin
    assert log.all_goals_reached, [g for g in log.goals if g.reached_at is None]
    assert not [e for e in log.events if e.kind == "stalled"]
    assert log.first_collision is None
