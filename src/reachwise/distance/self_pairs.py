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
from dataclasses import dataclass
from typing import Literal, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.distance.engine import PairQuery
from reachwise.errors import InputError
from reachwise.geometry.cloud import PointCloud
from reachwise.geometry.mesh_distance import segment_closest_parameters
from reachwise.kinematics.bodies import Body, adjacent_bodies

__all__ = [
    "ALWAYS_FRACTION",
    "Capsule",
    "PairRule",
    "SelfPairs",
    "adjacent_reason",
    "always_within",
    "bounding_capsule",
    "capsule_distances",
    "pair_hits",
    "random_configurations",
    "self_collision_pairs",
]

Rule = Literal["adjacent", "always", "never", "watched"]


class ChainLike(Protocol):
    """What the computation needs of a robot (``reachwise.kinematics.Robot`` has it)."""

    @property
    def name(self) -> str: ...

    @property
    def n(self) -> int: ...

    @property
    def link_names(self) -> tuple[str, ...]: ...

    @property
    def movable_joints(self) -> tuple[int, ...]: ...

    @property
    def lower(self) -> NDArray[np.float64]: ...

    @property
    def upper(self) -> NDArray[np.float64]: ...

    @property
    def body_tree(self) -> Mapping[str, Body]: ...

    @property
    def body_names(self) -> tuple[str, ...]: ...

    def link_index(self, link: str) -> int: ...

    def fk_all(self, q: ArrayLike) -> NDArray[np.float64]: ...


@dataclass(frozen=True)
class PairRule:
    """One link pair: ``rule`` is ``adjacent``, ``always`` or ``never`` (excluded) or
    ``watched``;
    ``detail`` says why in words; ``home_distance`` (m) is the exact distance at the
    home configuration (``inf`` for adjacent pairs, which are not measured);
    ``review`` marks a watched pair within the margin at home; ``margin`` (m) is a
    watched pair's own margin between the surfaces when it has one (a structurally
    close pair, module docstring), else ``None`` (the pairs' common margin)."""

    a: str
    b: str
    rule: Rule
    detail: str
    home_distance: float = math.inf
    review: bool = False
    margin: float | None = None


@dataclass(frozen=True, eq=False)
class SelfPairs:
    """The self-collision pairs of ``robot`` (see the module docstring)."""

    robot: str
    margin: float
    samples: int
    seed: int
    home: NDArray[np.float64]
    pairs: tuple[PairRule, ...]

    @property
    def watched(self) -> tuple[tuple[str, str], ...]:
        return tuple((p.a, p.b) for p in self.pairs if p.rule == "watched")

    @property
    def excluded(self) -> tuple[PairRule, ...]:
        return tuple(p for p in self.pairs if p.rule != "watched")

    @property
    def review(self) -> tuple[PairRule, ...]:
        return tuple(p for p in self.pairs if p.review)

    @property
    def margins(self) -> dict[tuple[str, str], float]:
        """Each watched pair's margin (m, between the surfaces): its own, else
        :attr:`margin`."""
        return {
            (p.a, p.b): self.margin if p.margin is None else p.margin
            for p in self.pairs
            if p.rule == "watched"
        }

    @property
    def always(self) -> tuple[PairRule, ...]:
        """The pairs excluded as always within the margin (module docstring)."""
        return tuple(p for p in self.pairs if p.rule == "always")


@dataclass(frozen=True)
class Capsule:
    """A capsule bounding a cloud, in the cloud's frame: the segment ``p0``–``p1`` and
    ``radius`` (every point is within ``radius`` of the segment)."""

    p0: NDArray[np.float64]
    p1: NDArray[np.float64]
    radius: float


def bounding_capsule(points: ArrayLike) -> Capsule:
    """A capsule around ``points``: the segment spans their extent along the principal
    axis (through their mean), the radius is the largest distance to it."""
    P = np.asarray(points, dtype=float).reshape(-1, 3)
    c = P.mean(axis=0)
    X = P - c
    if len(P) > 1:
        _, _, vt = np.linalg.svd(X, full_matrices=False)
        axis = vt[0]
    else:
        axis = np.array([0.0, 0.0, 1.0])
    t = X @ axis
    lo, hi = float(t.min()), float(t.max())
    tc = np.clip(t, lo, hi)
    r = float(np.linalg.norm(X - tc[:, None] * axis[None, :], axis=1).max())
    return Capsule(c + lo * axis, c + hi * axis, r)


def capsule_distances(
    a0: NDArray[np.float64],
    a1: NDArray[np.float64],
    b0: NDArray[np.float64],
    b1: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Distances between segments ``a0``–``a1`` and ``b0``–``b1``, row by row (``(m, 3)``
    each), at their closest points
    (:func:`reachwise.geometry.mesh_distance.segment_closest_parameters`, Ericson's
    *Real-Time Collision Detection*, §5.1.9)."""
    s, t = segment_closest_parameters(a0, a1, b0, b1)
    pa = a0 + s[:, None] * (a1 - a0)
    pb = b0 + t[:, None] * (b1 - b0)
    return np.asarray(np.linalg.norm(pa - pb, axis=1), dtype=float)


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


class _Placer:
    """World poses of the link clouds for a batch of configurations, and their capsules."""

    def __init__(self, robot: ChainLike, clouds: Mapping[str, PointCloud]) -> None:
        self.robot = robot
        self.clouds = dict(clouds)
        self.index = {n: robot.link_index(n) for n in self.clouds}
        self.caps = {n: bounding_capsule(c.points) for n, c in self.clouds.items()}

    def segments(
        self, F: NDArray[np.float64], link: str
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        T = F[:, self.index[link]]
        cap = self.caps[link]
        R, p = T[:, :3, :3], T[:, :3, 3]
        return R @ cap.p0 + p, R @ cap.p1 + p

    def bounds(self, F: NDArray[np.float64], la: str, lb: str) -> NDArray[np.float64]:
        """Lower bounds of the cloud distance of (la, lb) for every configuration."""
        a0, a1 = self.segments(F, la)
        b0, b1 = self.segments(F, lb)
        return capsule_distances(a0, a1, b0, b1) - self.caps[la].radius - self.caps[lb].radius


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
    placer = _Placer(robot, clouds)
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


#: Local search: how many closest samples it starts from, perturbations per step, and its
#: step sizes (fraction of each joint's range).
_SEEDS = 5
_BATCH = 16
_STEP0, _STEP_MIN = 0.05, 1e-3


class _LocalSearch:
    """Descends the exact distance of one pair from its closest random samples: a few
    random perturbations per step inside the limits, the best kept, the step halved
    when none is better; stops as soon as the pair comes within the margin."""

    def __init__(
        self,
        robot: ChainLike,
        a: PointCloud,
        b: PointCloud,
        ia: int,
        ib: int,
        margin: float,
    ) -> None:
        self.robot, self.ia, self.ib, self.margin = robot, ia, ib, margin
        self.query = PairQuery(a, b, margin=max(4.0 * margin, 0.5))
        self.lo = np.asarray(robot.lower, float)
        self.hi = np.asarray(robot.upper, float)

    def run(
        self, Q: NDArray[np.float64], F: NDArray[np.float64], bounds: NDArray[np.float64], seed: int
    ) -> float:
        """The smallest distance found (``inf`` when every sample is far beyond)."""
        # the closest samples by exact distance: in order of their lower bound, until the
        # bound exceeds the k-th best distance (no later sample can be closer); each
        # query is bounded by that k-th best, so a farther sample costs little
        found: list[tuple[float, int]] = []
        cap = self.query.margin
        for s in np.argsort(bounds, kind="stable"):
            kth = found[_SEEDS - 1][0] if len(found) >= _SEEDS else cap
            if bounds[s] > kth:
                break
            r = self.query(F[s, self.ia], F[s, self.ib], margin=kth)
            if not r.no_risk:
                found.append((r.distance, int(s)))
                found.sort()
                del found[_SEEDS:]
        best_d = found[0][0] if found else math.inf
        if not math.isfinite(best_d):
            return best_d
        rng = np.random.default_rng([int(seed), self.ia, self.ib])
        span = self.hi - self.lo
        for dq, s in found:
            q = Q[s].copy()
            step = _STEP0
            while step >= _STEP_MIN and dq > self.margin:
                trial = np.clip(q + rng.normal(0.0, 1.0, (_BATCH, len(q))) * step * span,
                                self.lo, self.hi)  # fmt: skip
                Ft = np.asarray(self.robot.fk_all(trial), dtype=float)
                dt = np.array(  # only a closer trial matters: bound each query by dq
                    [self.query(f[self.ia], f[self.ib], margin=dq).distance for f in Ft]
                )
                k = int(np.argmin(dt))
                if dt[k] < dq:
                    q, dq = trial[k], float(dt[k])
                else:
                    step *= 0.5
            best_d = min(best_d, dq)
            if best_d <= self.margin:
                break
        return best_d


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
    if not (isinstance(margin, int | float) and math.isfinite(margin) and margin > 0):
        raise InputError(robot.name, "margin", f"must be finite and > 0, got {margin!r}")
    if int(samples) < 1:
        raise InputError(robot.name, "samples", f"must be ≥ 1, got {samples!r}")
    rank = {n: i for i, n in enumerate(robot.body_names)}
    for link in clouds:
        if link not in rank:
            raise InputError(robot.name, "clouds", f"no link {link!r}")
    idx = {n: robot.link_index(n) for n in clouds}
    links = sorted(clouds, key=rank.__getitem__)
    lo, hi = np.asarray(robot.lower, float), np.asarray(robot.upper, float)
    q_home = np.clip(np.zeros(robot.n), lo, hi) if home is None else np.asarray(home, float)
    if q_home.shape != (robot.n,) or not np.isfinite(q_home).all():
        raise InputError(robot.name, "home", f"expected {robot.n} finite joint values")
    F_home = np.asarray(robot.fk_all(q_home), dtype=float)
    Q = random_configurations(robot, samples, seed)
    F = np.asarray(robot.fk_all(Q), dtype=float)
    placer = _Placer(robot, clouds)
    out: list[PairRule] = []
    for i, la in enumerate(links):
        for lb in links[i + 1 :]:
            why = adjacent_reason(robot, links, la, lb)
            if why is not None:
                out.append(PairRule(la, lb, "adjacent", why))
                continue
            # a cloud distance overstates the surfaces' by up to both clouds' resolutions
            coverage = clouds[la].resolution + clouds[lb].resolution
            m = margin + coverage
            within = f"{margin:g} m" + (f" ({m:g} m between the clouds)" if coverage else "")
            query = PairQuery(clouds[la], clouds[lb])
            d_home = query(F_home[idx[la]], F_home[idx[lb]]).distance
            query = PairQuery(clouds[la], clouds[lb], margin=m)
            bounds = placer.bounds(F, la, lb)
            band = always_within(query, F, idx[la], idx[lb], bounds)
            if band is not None:
                out.append(_always_rule(la, lb, band, margin, coverage, len(Q), d_home))
                continue
            order = np.argsort(bounds, kind="stable")
            order = order[bounds[order] <= m]
            hit = -1
            for s in order:
                if not query(F[s, idx[la]], F[s, idx[lb]]).no_risk:
                    hit = int(s)
                    break
            review = d_home <= m
            closest = math.inf
            if hit < 0 and not review and local_search:
                search = _LocalSearch(robot, clouds[la], clouds[lb], idx[la], idx[lb], m)
                closest = search.run(Q, F, placer.bounds(F, la, lb), seed)
                if closest > m:
                    detail = (
                        f"never within {within}: {len(Q)} random configurations and a local "
                        f"search from the {_SEEDS} closest (closest found {closest:.3f} m)"
                    )
                    out.append(PairRule(la, lb, "never", detail, d_home))
                    continue
            elif hit < 0 and not review:
                detail = f"never within {within} in {len(Q)} random configurations"
                out.append(PairRule(la, lb, "never", detail, d_home))
                continue
            if review:
                detail = f"within the margin at the home configuration ({d_home:.3f} m): review"
            elif hit >= 0:
                detail = f"within the margin in random configuration {hit}"
            else:
                detail = f"within the margin after a local search ({closest:.3f} m)"
            out.append(PairRule(la, lb, "watched", detail, d_home, review))
    return SelfPairs(robot.name, float(margin), len(Q), int(seed), q_home, tuple(out))
