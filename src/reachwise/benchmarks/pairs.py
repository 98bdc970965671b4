"""``reachwise bench pairs``: automatic self-collision pairs of a real arm.

The example-robot-data Panda (the ``robots`` extra), its link clouds (the default: each
covers its shapes within 1 cm, about 10 000 points in all; 11 URDF links), margin 5 cm:

- ``pairs.compute_s``: :func:`reachwise.distance.self_pairs.self_collision_pairs` with
  10 000 random configurations (``--quick``: 1 000) — batched FK, capsule bounds, exact
  queries only where a bound is within the margin, then the local search;
- ``pairs.sampling_s``: the same without the local search (sampling alone, MoveIt's
  rule), and ``pairs.sampling_without_bounds_s``, its baseline: an exact (margin-bounded)
  query for every configuration of every non-adjacent pair until its first hit;
- ``pairs.recall_pairs`` / ``pairs.recall_events``: against a separate set of 10 000
  configurations, the share of the pairs that come within the margin there (and of all
  such configuration-pair events) that are watched, among the pairs not excluded as
  ``always`` (within the margin nearly everywhere: left out on purpose); within the
  margin means within it plus both clouds' resolutions between the clouds, as the rules
  count it.

Targets: 10 000 samples in seconds (≤ 10 s), recall ≥ 99.9 %.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

from reachwise.benchmarks._harness import BenchReport, Target

if TYPE_CHECKING:
    from reachwise.distance.self_pairs import SelfPairs
    from reachwise.geometry.cloud import PointCloud
    from reachwise.kinematics.robot import Robot

URDF = "package://example-robot-data/robots/panda_description/urdf/panda.urdf"
MARGIN = 0.05


def run(quick: bool = False) -> BenchReport:
    """Time the Panda's automatic pairs and measure their recall (see the docstring)."""
    rep = BenchReport("pairs")
    arm = _panda(rep)
    if arm is None:
        return rep
    robot, clouds = arm
    samples = 1_000 if quick else 10_000
    found, sampled = _timings(rep, robot, clouds, samples)
    reach = _recall(rep, robot, clouds, found, sampled)
    rep.targets["pairs.compute_s"] = Target(rep.metrics["pairs.compute_s"], 10.0)
    rep.targets["pairs.recall_events"] = Target(
        rep.metrics["pairs.recall_events"], 0.999, higher_is_better=True
    )
    rep.notes.append(
        f"Panda (example-robot-data), clouds covering their shapes within 1 cm "
        f"({rep.metrics['pairs.cloud_points']:.0f} points), margin {MARGIN} m ({reach:g} m "
        f"between the clouds), {samples} random configurations; recall against a separate "
        "set of 10 000"
    )
    return rep


def _panda(rep: BenchReport) -> tuple[Robot, dict[str, PointCloud]] | None:
    """The example-robot-data Panda and its link clouds, or ``None`` (with a note in
    ``rep``) when the package is not installed."""
    import logging

    from reachwise.errors import InputError
    from reachwise.io.mesh_uri import resolve_uri
    from reachwise.io.robot_clouds import link_clouds
    from reachwise.io.robot_file import load_robot

    try:
        path = resolve_uri(URDF, robot_file=None, source="bench pairs", field="robot")
    except InputError:
        rep.notes.append(
            'left out: example-robot-data is not installed (pip install "reachwise[robots]")'
        )
        return None
    logging.getLogger("reachwise.io.urdf").setLevel(logging.ERROR)
    robot = load_robot(path, tip="panda_hand")
    return robot, link_clouds(robot)


def _timings(
    rep: BenchReport, robot: Robot, clouds: dict[str, PointCloud], samples: int
) -> tuple[SelfPairs, SelfPairs]:
    """Time the pairs with and without the local search, and the sampling's baseline
    without capsule bounds; returns the two answers."""
    from reachwise.distance.engine import PairQuery
    from reachwise.distance.self_pairs import random_configurations, self_collision_pairs

    self_collision_pairs(robot, clouds, MARGIN, samples=50)  # compile outside the timing
    t0 = time.perf_counter()
    found = self_collision_pairs(robot, clouds, MARGIN, samples=samples, seed=0)
    rep.metrics["pairs.compute_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    sampled = self_collision_pairs(
        robot, clouds, MARGIN, samples=samples, seed=0, local_search=False
    )
    rep.metrics["pairs.sampling_s"] = time.perf_counter() - t0
    others = [(p.a, p.b) for p in found.pairs if p.rule != "adjacent"]
    reach = _reach(clouds)
    Q = random_configurations(robot, samples, 0)
    t0 = time.perf_counter()
    F = robot.fk_all(Q)
    index = {n: robot.link_index(n) for n in clouds}
    for a, b in others:
        query = PairQuery(clouds[a], clouds[b], margin=reach)
        for s in range(len(Q)):
            if not query(F[s, index[a]], F[s, index[b]]).no_risk:
                break
    rep.metrics["pairs.sampling_without_bounds_s"] = time.perf_counter() - t0
    rep.ratios["sampling_without_bounds_over_sampling"] = (
        rep.metrics["pairs.sampling_without_bounds_s"] / rep.metrics["pairs.sampling_s"]
    )
    return found, sampled


def _reach(clouds: dict[str, PointCloud]) -> float:
    """The rules' reach between two clouds: the margin plus both resolutions."""
    return MARGIN + 2.0 * max(c.resolution for c in clouds.values())


def _recall(
    rep: BenchReport,
    robot: Robot,
    clouds: dict[str, PointCloud],
    found: SelfPairs,
    sampled: SelfPairs,
) -> float:
    """The pair counts and the recall of ``found`` (and of ``sampled``, the sampling
    alone) against a separate set of 10 000 configurations, added to ``rep``; returns
    the reach between the clouds it counts within."""
    from reachwise.distance.self_pairs import pair_hits, random_configurations

    others = [(p.a, p.b) for p in found.pairs if p.rule != "adjacent"]
    reach = _reach(clouds)
    # recall over the pairs a rule may watch: a pair excluded as "always" (within the
    # margin nearly everywhere) is left out on purpose, its events are not misses
    always = {(p.a, p.b) for p in found.pairs if p.rule == "always"}
    judged = [p for p in others if p not in always]
    hits = pair_hits(robot, clouds, judged, reach, random_configurations(robot, 10_000, 777))
    events = hits.sum(axis=0)
    watched = set(found.watched)
    close = [p for p, e in zip(judged, events, strict=True) if e > 0]
    caught = sum(int(e) for p, e in zip(judged, events, strict=True) if p in watched)
    rep.metrics["pairs.cloud_points"] = float(sum(len(c.points) for c in clouds.values()))
    rep.metrics["pairs.pairs"] = float(len(found.pairs))
    rep.metrics["pairs.watched"] = float(len(watched))
    rep.metrics["pairs.excluded_adjacent"] = float(len(found.pairs) - len(others))
    rep.metrics["pairs.excluded_never"] = float(sum(p.rule == "never" for p in found.pairs))
    rep.metrics["pairs.excluded_always"] = float(len(always))
    rep.metrics["pairs.recall_pairs"] = len(set(close) & watched) / max(len(close), 1)
    rep.metrics["pairs.recall_events"] = caught / max(int(events.sum()), 1)
    alone = set(sampled.watched)
    rep.metrics["pairs.sampling_alone_recall_pairs"] = len(set(close) & alone) / max(len(close), 1)
    return reach
