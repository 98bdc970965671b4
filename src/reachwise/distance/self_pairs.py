"""Which link pairs of a robot to watch for self-collision, chosen automatically.

The method of MoveIt's Setup Assistant ("allowed collision matrix",
``compute_default_collisions.cpp``), with reachwise's exact cloud distances and a
margin instead of a contact test:

1. **adjacent** — MoveIt's rule on the robot's bodies
   (:func:`reachwise.kinematics.bodies.adjacent_bodies`): two links one joint joins, or
   joined only through links without shapes; and links rigidly joined (no moving joint
   between their frames: their distance cannot change): excluded. A hand fixed to a
   flange is thus checked against the wrist links beyond the joint that moves it.
2. **always** — a pair within the margin in at least :data:`ALWAYS_FRACTION` (95 %) of
   the ``samples`` random joint vectors (its clearance hardly ever exceeds the margin:
   structurally close, like the two wrist links of a UR arm) would repel in nearly
   every configuration, pushing the arm away from any goal. When its clouds stay
   farther apart than their resolutions in every sample (the true surfaces never touch
   there) it is excluded, with that share and the range of its clearance in its
   detail: MoveIt's ``Always``. A pair whose clouds come within their resolutions
   somewhere (it may touch, like the Panda's forearm and flange when joint 6 folds) is
   watched with a **margin of its own** instead (:attr:`PairRule.margin`): its
   clearance at the 5 % quantile less both resolutions, at least 0 (the clouds kept
   their resolutions apart, so the surfaces never touch), so it acts only where the
   pair closes in. A pair whose clouds are within their resolutions in 95 % of the
   samples or more is beyond what its clouds can tell (like a Talos wrist and its
   force-torque sensor, a few millimetres apart, with 1 cm clouds): it is judged on its
   cloud distance as it is — excluded as ``always`` when that is within the margin in
   95 % of the samples, else watched with the margin between the clouds (its own
   margin, the margin less both resolutions, is then below 0, and its detail says the
   controller cannot promise its surfaces apart; finer clouds would).
3. **home** — every other pair is measured at the home (start) configuration; a pair
   within the margin there is reported for review (MoveIt disables such pairs as
   "default" collisions; a collision tool keeps them watched and lets the user
   decide).
4. **never** — ``samples`` (≥ 10 000 by default) random joint vectors, uniform within
   the joint limits: a pair that never comes within the margin in any of them, nor in a
   local search that descends its distance from the 5 closest of them, is excluded
   (the local search is ours: sampling alone misses pairs that come close only in a
   small region of the joint space).
5. the rest is **watched**.

Distances are conservative by the clouds' ``resolution``
(:attr:`~reachwise.geometry.cloud.PointCloud.resolution`): a cloud covering its shapes
within ``r`` has a point within ``r`` of every surface point, so two clouds' distance
exceeds their surfaces' by at most ``r_a + r_b``; every rule compares a pair's cloud
distance with its margin plus both resolutions (a margin is between the true surfaces).

It is pure maths (robot, clouds and a random generator in, a :class:`SelfPairs` out)
and fast: the forward kinematics of all samples is one batched call, each link cloud is
bounded by a capsule (a segment along its principal axis and a radius), so the
capsule-capsule distance — a lower bound of the cloud distance — is evaluated for
every sample at once with numpy, and only samples whose bound is within the margin get
an exact query (:class:`~reachwise.distance.engine.PairQuery`, margin-bounded, which
stops as soon as "beyond the margin" is certain), nearest bound first; a pair is
settled as watched at its first sample within the margin.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.distance.engine import PairQuery
from reachwise.distance.link_capsules import (
    Capsule,
    LinkCapsules,
    bounding_capsule,
    capsule_distances,
)
from reachwise.distance.self_pairs_search import SEEDS, LocalSearch
from reachwise.distance.self_pairs_types import ChainLike, PairRule, Rule, SelfPairs
from reachwise.errors import InputError
from reachwise.geometry.cloud import PointCloud
from reachwise.kinematics.bodies import adjacent_bodies

__all__ = [
    "ALWAYS_FRACTION",
    "Capsule",
    "ChainLike",
    "PairRule",
    "Rule",
    "SelfPairs",
    "adjacent_reason",
    "always_within",
    "bounding_capsule",
    "capsule_distances",
    "pair_hits",
    "random_configurations",
    "self_collision_pairs",
]


def adjacent_reason(robot: ChainLike, links: list[str], la: str, lb: str) -> str | None:
    """Why links ``la`` and ``lb`` count as adjacent (see the module docstring), or
    ``None``; ``links`` are the robot's links with clouds."""
    ia, ib = sorted((robot.link_index(la), robot.link_index(lb)))
    movable = set(robot.movable_joints)
    between = sum(1 for j in range(ia, ib) if j in movable)
    if between == 0:
        return "rigidly connected (no moving joint between them)"
    tree = robot.body_tree
    for x, y in ((la, lb), (lb, la)):
        body = tree.get(x)
        if body is not None and body.parent == y:
            return f"joined by one joint{f' ({body.joint})' if body.joint else ''}"
    if adjacent_bodies(tree, links, la, lb):
        return "no link with shapes between them (MoveIt: joined through links without shapes)"
    return None


def random_configurations(robot: ChainLike, samples: int, seed: int) -> NDArray[np.float64]:
    """``samples`` joint vectors uniform within the limits (``numpy.random.default_rng(
    seed)``); unbounded joints are an :class:`InputError`."""
    lo, hi = np.asarray(robot.lower, float), np.asarray(robot.upper, float)
    if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
        raise InputError(robot.name, "limits", "random configurations need finite joint limits")
    rng = np.random.default_rng(seed)
    return np.asarray(rng.uniform(lo, hi, (int(samples), robot.n)), dtype=float)


def pair_hits(
    robot: ChainLike,
    clouds: Mapping[str, PointCloud],
    pairs: list[tuple[str, str]],
    margin: float,
    Q: ArrayLike,
) -> NDArray[np.bool_]:
    """``(m, len(pairs))``: whether each pair's exact cloud distance is within
    ``margin`` at each configuration of ``Q`` (capsule bounds skip the far ones)."""
    Qa = np.asarray(Q, dtype=float).reshape(-1, robot.n)
    F = np.asarray(robot.fk_all(Qa), dtype=float)
    placer = LinkCapsules(clouds, {n: robot.link_index(n) for n in clouds})
    out = np.zeros((len(Qa), len(pairs)), dtype=bool)
    for k, (la, lb) in enumerate(pairs):
        query = PairQuery(clouds[la], clouds[lb], margin=margin)
        ia, ib = placer.index[la], placer.index[lb]
        for s in np.flatnonzero(placer.bounds(F, la, lb) <= margin):
            out[s, k] = not query(F[s, ia], F[s, ib]).no_risk
    return out


#: The share of the random configurations a pair must be within the margin in to be
#: excluded as ``always`` (MoveIt's Setup Assistant disables a pair as "always in
#: collision" from the same share of its samples, 0.95 by default).
ALWAYS_FRACTION = 0.95


def always_within(
    query: PairQuery, F: NDArray[np.float64], ia: int, ib: int, bounds: NDArray[np.float64]
) -> tuple[float, float, float, NDArray[np.float64]] | None:
    """``(share, smallest, largest, within)``: the share of the configurations ``F`` in
    which a pair is within ``query.margin``, the smallest and largest clearance over
    them and the clearances within the margin, sorted, when that share is at least
    :data:`ALWAYS_FRACTION`, else ``None``. ``bounds`` are its capsule lower bounds:
    too many bounds beyond the margin settle "not always" at once, and the samples are
    queried farthest bound first, so a pair that often leaves the margin does so within
    the first queries. The largest clearance is exact for the samples within the margin
    and ``≥`` the margin otherwise."""
    m = len(bounds)
    allowed = math.floor((1.0 - ALWAYS_FRACTION) * m + 1e-9)
    if int(np.count_nonzero(bounds > query.margin)) > allowed:
        return None
    out, lo, hi = 0, math.inf, 0.0
    seen: list[float] = []
    for s in np.argsort(-bounds, kind="stable"):
        r = query(F[s, ia], F[s, ib])
        if r.no_risk:
            out += 1
            hi = max(hi, query.margin)
            if out > allowed:
                return None
            continue
        lo, hi = min(lo, r.distance), max(hi, r.distance)
        seen.append(r.distance)
    return (m - out) / m, lo, hi, np.sort(np.asarray(seen, dtype=float))


def _always_rule(
    a: str,
    b: str,
    band: tuple[float, float, float, NDArray[np.float64]],
    margin: float,
    coverage: float,
    samples: int,
    home: float,
) -> PairRule:
    """The rule of a pair within ``margin`` (between the surfaces) in most of the
    ``samples``, with :func:`always_within`'s ``band`` (cloud distances; ``coverage``:
    both clouds' resolutions): ``always`` (excluded) when its clouds stay more than
    ``coverage`` apart; else watched with its own margin, the clearance it exceeds in
    :data:`ALWAYS_FRACTION` of the samples less ``coverage``, at least 0; a pair whose
    clouds are within ``coverage`` in :data:`ALWAYS_FRACTION` of them is judged on its
    cloud distance as it is (module docstring)."""
    within = f"{margin:g} m" + (
        f" ({margin + coverage:g} m between the clouds)" if coverage else ""
    )
    seen = (
        f"in {100 * band[0]:.1f} % of {samples} random configurations (clearance "
        f"{band[1]:.4f} to {band[2]:.4f} m)"
    )
    if band[1] > coverage:
        return PairRule(a, b, "always", f"always within {within}: {seen}", home)
    k = math.floor((1.0 - ALWAYS_FRACTION) * samples + 1e-9)
    low = float(band[3][min(k, len(band[3]) - 1)])
    if int(np.count_nonzero(band[3] <= coverage)) >= ALWAYS_FRACTION * samples:
        # the clouds are too coarse for this pair: judged on the cloud distance as it is
        share = int(np.count_nonzero(band[3] <= margin)) / samples
        if share >= ALWAYS_FRACTION:
            detail = (
                f"always within {within}: {seen}; its clouds are within their resolutions "
                f"in {100 * ALWAYS_FRACTION:g} % of them or more, and within {margin:g} m "
                f"in {100 * share:.1f} %"
            )
            return PairRule(a, b, "always", detail, home)
        detail = (
            f"within {within} {seen}; its clouds are within their resolutions in "
            f"{100 * ALWAYS_FRACTION:g} % of them or more (too coarse to promise its "
            f"surfaces apart): watched on the cloud distance as it is, its own margin "
            f"{margin - coverage:.4f} m (the clouds kept {margin:g} m apart, within it in "
            f"{100 * share:.1f} %; finer clouds would make it conservative)"
        )
        return PairRule(a, b, "watched", detail, home, home <= margin, margin=margin - coverage)
    low = max(low, coverage)  # a margin of 0 (surfaces kept apart) acts rarely enough
    own = low - coverage
    share = int(np.count_nonzero(band[3] <= low)) / samples
    detail = (
        f"within {within} {seen}, its clouds within their resolutions somewhere: watched "
        f"with its own margin {own:.4f} m (within it in {100 * share:.1f} %)"
    )
    return PairRule(a, b, "watched", detail, home, home <= low, margin=own)


class _Judge:
    """The rules of one robot's non-adjacent pairs, from its link frames at home and at
    the random configurations (module docstring, rules 2–5)."""

    def __init__(
        self,
        robot: ChainLike,
        clouds: Mapping[str, PointCloud],
        margin: float,
        q_home: NDArray[np.float64],
        Q: NDArray[np.float64],
    ) -> None:
        self.robot, self.clouds, self.margin, self.Q = robot, clouds, margin, Q
        self.idx = {n: robot.link_index(n) for n in clouds}
        self.F_home = np.asarray(robot.fk_all(q_home), dtype=float)
        self.F = np.asarray(robot.fk_all(Q), dtype=float)
        self.capsules = LinkCapsules(clouds, self.idx)

    def rule(self, la: str, lb: str, seed: int, local_search: bool) -> PairRule:
        """The rule of the pair (``la``, ``lb``), not adjacent."""
        clouds, idx, F, margin = self.clouds, self.idx, self.F, self.margin
        # a cloud distance overstates the surfaces' by up to both clouds' resolutions
        coverage = clouds[la].resolution + clouds[lb].resolution
        m = margin + coverage
        query = PairQuery(clouds[la], clouds[lb])
        d_home = query(self.F_home[idx[la]], self.F_home[idx[lb]]).distance
        query = PairQuery(clouds[la], clouds[lb], margin=m)
        bounds = self.capsules.bounds(F, la, lb)
        band = always_within(query, F, idx[la], idx[lb], bounds)
        if band is not None:
            return _always_rule(la, lb, band, margin, coverage, len(self.Q), d_home)
        hit = self._first_hit(query, la, lb, bounds)
        review = d_home <= m
        if hit >= 0 or review:
            detail = (
                f"within the margin at the home configuration ({d_home:.3f} m): review"
                if review
                else f"within the margin in random configuration {hit}"
            )
            return PairRule(la, lb, "watched", detail, d_home, review)
        within = f"{margin:g} m" + (f" ({m:g} m between the clouds)" if coverage else "")
        if not local_search:
            detail = f"never within {within} in {len(self.Q)} random configurations"
            return PairRule(la, lb, "never", detail, d_home)
        search = LocalSearch(self.robot, clouds[la], clouds[lb], idx[la], idx[lb], m)
        closest = search.run(self.Q, F, bounds, seed)
        if closest > m:
            detail = (
                f"never within {within}: {len(self.Q)} random configurations and a local "
                f"search from the {SEEDS} closest (closest found {closest:.3f} m)"
            )
            return PairRule(la, lb, "never", detail, d_home)
        detail = f"within the margin after a local search ({closest:.3f} m)"
        return PairRule(la, lb, "watched", detail, d_home, review)

    def _first_hit(self, query: PairQuery, la: str, lb: str, bounds: NDArray[np.float64]) -> int:
        """The first random configuration, nearest capsule bound first, in which the pair
        is within ``query.margin``, or -1."""
        order = np.argsort(bounds, kind="stable")
        order = order[bounds[order] <= query.margin]
        ia, ib = self.idx[la], self.idx[lb]
        for s in order:
            if not query(self.F[s, ia], self.F[s, ib]).no_risk:
                return int(s)
        return -1


def _home_configuration(robot: ChainLike, home: ArrayLike | None) -> NDArray[np.float64]:
    """``home`` checked, or 0 moved into the limits when it is ``None``."""
    lo, hi = np.asarray(robot.lower, float), np.asarray(robot.upper, float)
    q_home = np.clip(np.zeros(robot.n), lo, hi) if home is None else np.asarray(home, float)
    if q_home.shape != (robot.n,) or not np.isfinite(q_home).all():
        raise InputError(robot.name, "home", f"expected {robot.n} finite joint values")
    return q_home


def _linked_clouds(
    robot: ChainLike, clouds: Mapping[str, PointCloud], margin: float, samples: int
) -> list[str]:
    """The links of ``clouds`` in the robot's body order, after checking the inputs."""
    if not (isinstance(margin, int | float) and math.isfinite(margin) and margin > 0):
        raise InputError(robot.name, "margin", f"must be finite and > 0, got {margin!r}")
    if int(samples) < 1:
        raise InputError(robot.name, "samples", f"must be ≥ 1, got {samples!r}")
    rank = {n: i for i, n in enumerate(robot.body_names)}
    for link in clouds:
        if link not in rank:
            raise InputError(robot.name, "clouds", f"no link {link!r}")
    return sorted(clouds, key=rank.__getitem__)


def self_collision_pairs(
    robot: ChainLike,
    clouds: Mapping[str, PointCloud],
    margin: float,
    *,
    samples: int = 10_000,
    seed: int = 0,
    home: ArrayLike | None = None,
    local_search: bool = True,
) -> SelfPairs:
    """The self-collision pairs of ``robot`` whose link ``clouds`` (each in its link's
    frame, keyed by link name) are given (see the module docstring). ``margin`` (m): the
    distance within which a pair counts as close, between the true surfaces: a cloud
    distance overstates it by up to both clouds' ``resolution`` (a cloud point can be
    that far from the surface point nearest the other link), so each pair's rules
    compare its cloud distance with ``margin`` plus both resolutions; ``home``: the start
    configuration
    (default: 0 moved into the limits); ``local_search=False`` excludes on the samples
    alone (MoveIt's rule; for comparison)."""
    links = _linked_clouds(robot, clouds, margin, samples)
    q_home = _home_configuration(robot, home)
    Q = random_configurations(robot, samples, seed)
    judge = _Judge(robot, clouds, margin, q_home, Q)
    out: list[PairRule] = []
    for i, la in enumerate(links):
        for lb in links[i + 1 :]:
            why = adjacent_reason(robot, links, la, lb)
            if why is not None:
                out.append(PairRule(la, lb, "adjacent", why))
            else:
                out.append(judge.rule(la, lb, seed, local_search))
    return SelfPairs(robot.name, float(margin), len(Q), int(seed), q_home, tuple(out))
