"""Automatic self-collision pairs (MoveIt Setup Assistant method, exact distances).

The capsule bound against brute force, the hit test against k-d trees, and the
Panda's pairs against a separate set of 10 000 random configurations: every pair that
comes within the margin there is watched, adjacent pairs are not, the file lists the
rule behind each exclusion.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial import cKDTree

import reachwise
from reachwise.distance.self_pairs import (
    ALWAYS_FRACTION,
    adjacent_reason,
    bounding_capsule,
    capsule_distances,
    pair_hits,
    random_configurations,
    self_collision_pairs,
)
from reachwise.errors import InputError
from reachwise.geometry.cloud import PointCloud
from reachwise.io.pairs_file import RULES, load_pairs, save_pairs
from reachwise.kinematics.robot import Joint, LinkGeometry, Robot
from tests._real_arms import arm_path, needs_erd

MARGIN = 0.05


def test_segment_distances_equal_brute_force(rng: np.random.Generator) -> None:
    m = 400
    a0, a1, b0, b1 = (rng.normal(size=(m, 3)) for _ in range(4))
    a1[:40] = a0[:40]  # points
    b1[40:80] = b0[40:80]
    a1[80:90], b1[80:90] = a0[80:90], b0[80:90]
    b1[100:150] = b0[100:150] + 0.7 * (a1[100:150] - a0[100:150])  # parallel
    d = capsule_distances(a0, a1, b0, b1)
    t = np.linspace(0.0, 1.0, 1001)
    for i in range(m):
        pa = a0[i] + t[:, None] * (a1[i] - a0[i])
        pb = b0[i] + t[:, None] * (b1[i] - b0[i])
        brute = cKDTree(pb).query(pa)[0].min()
        assert d[i] <= brute + 1e-12 and brute - d[i] < 2e-3


def test_bounding_capsule_holds_every_point(rng: np.random.Generator) -> None:
    P = rng.normal(size=(500, 3)) * (0.3, 0.05, 0.08) + (1.0, 2.0, 3.0)
    cap = bounding_capsule(P)
    d = capsule_distances(np.broadcast_to(cap.p0, P.shape), np.broadcast_to(cap.p1, P.shape), P, P)
    assert d.max() <= cap.radius + 1e-12
    assert cap.radius < 0.35  # follows the long axis, far tighter than a sphere


def _stick_robot() -> Robot:
    """Five revolute joints about z/y with 0.3 m sticks; link_3 has no shape."""
    joints = tuple(
        Joint("revolute", a=0.3 if i else 0.0, alpha=(np.pi / 2 if i % 2 else 0.0),
              limits=(-2.5, 2.5))
        for i in range(5)
    )  # fmt: skip
    box = LinkGeometry("box", size=(0.3, 0.04, 0.04), origin=_at(0.15))
    geometry = {f"link_{i}": box for i in (1, 2, 4, 5)}
    return Robot("sticks", joints, geometry=geometry)


def _at(x: float) -> tuple[tuple[float, ...], ...]:
    T = np.eye(4)
    T[0, 3] = x
    return tuple(map(tuple, T))


def test_adjacency_rules() -> None:
    r = _stick_robot()
    links = ["link_1", "link_2", "link_4", "link_5"]
    assert adjacent_reason(r, links, "link_1", "link_2") == "joined by one joint"
    assert "no link with shapes between" in str(adjacent_reason(r, links, "link_2", "link_4"))
    assert adjacent_reason(r, links, "link_1", "link_4") is None
    fixed = Robot("f", (Joint("revolute"), Joint("fixed", a=0.2), Joint("revolute")))
    assert "rigidly" in str(adjacent_reason(fixed, ["link_1", "link_2"], "link_1", "link_2"))


def test_pair_hits_equal_kd_tree_distances(rng: np.random.Generator) -> None:
    r = _stick_robot()
    clouds = reachwise.link_clouds(r, points=150)
    pairs = [("link_1", "link_4"), ("link_1", "link_5"), ("link_2", "link_5")]
    Q = random_configurations(r, 300, 5)
    H = pair_hits(r, clouds, pairs, 0.08, Q)
    F = r.fk_all(Q)
    for k, (a, b) in enumerate(pairs):
        ia, ib = r.link_index(a), r.link_index(b)
        for s in range(len(Q)):
            pa = clouds[a].points @ F[s, ia, :3, :3].T + F[s, ia, :3, 3]
            pb = clouds[b].points @ F[s, ib, :3, :3].T + F[s, ib, :3, 3]
            assert H[s, k] == (cKDTree(pb).query(pa)[0].min() <= 0.08)
    assert H.any() and not H.all()  # both outcomes occur


def test_bad_inputs_are_input_errors() -> None:
    r = _stick_robot()
    clouds = reachwise.link_clouds(r, points=50)
    with pytest.raises(InputError, match="margin"):
        self_collision_pairs(r, clouds, -1.0)
    with pytest.raises(InputError, match="home"):
        self_collision_pairs(r, clouds, 0.05, samples=10, home=[0.0])
    with pytest.raises(InputError, match="no link"):
        self_collision_pairs(r, {"hand": PointCloud(np.zeros((3, 3)))}, 0.05, samples=10)
    unbounded = Robot("u", (Joint("prismatic"), Joint("revolute", a=1.0)))
    with pytest.raises(InputError, match="finite joint limits"):
        random_configurations(unbounded, 10, 0)


@needs_erd
def test_panda_pairs_recall_on_a_separate_set(tmp_path: Path) -> None:
    robot = reachwise.load_robot(arm_path("panda"), tip="panda_hand")
    clouds = reachwise.link_clouds(robot)
    found = self_collision_pairs(robot, clouds, MARGIN, samples=10_000, seed=0)
    adjacent = [(p.a, p.b) for p in found.pairs if p.rule == "adjacent"]
    # MoveIt's rule: the 7 pairs one joint joins, and the 6 pairs of link 7, the hand and
    # its fingers (rigidly joined); the hand is checked against link 6, beyond joint 7
    joined = [(f"panda_link{i}", f"panda_link{i + 1}") for i in range(7)]
    rigid = {"panda_link7", "panda_hand", "panda_leftfinger", "panda_rightfinger"}
    assert set(joined) <= set(adjacent) and len(adjacent) == 13
    assert all({a, b} <= rigid for a, b in set(adjacent) - set(joined))
    assert ("panda_link6", "panda_hand") not in adjacent
    assert not set(adjacent) & set(found.watched)
    always = [(p.a, p.b) for p in found.always]  # within the margin (nearly) everywhere
    others = [(p.a, p.b) for p in found.pairs if p.rule not in ("adjacent", "always")]
    Q = random_configurations(robot, 10_000, 777)
    share = pair_hits(robot, clouds, always, MARGIN, Q).mean(axis=0)
    assert np.all(share >= ALWAYS_FRACTION - 0.01), dict(zip(always, share, strict=True))
    hits = pair_hits(robot, clouds, others, MARGIN, Q)
    events = hits.sum(axis=0)
    watched = set(found.watched)
    caught = sum(int(e) for p, e in zip(others, events, strict=True) if p in watched)
    assert caught / events.sum() >= 0.999  # recall over (configuration, pair) events
    close = {p for p, e in zip(others, events, strict=True) if e > 0}
    assert len(close & watched) / len(close) >= 0.999  # and over pairs: all of them
    assert {p.rule for p in found.excluded} <= {"adjacent", "always", "never"}

    path = save_pairs(found, tmp_path / "pairs.yaml", source=robot.source or "")
    data = yaml.safe_load(path.read_text())
    assert data["rules"] == RULES and data["margin"] == MARGIN and data["samples"] == 10_000
    assert all(e["rule"] in RULES and e["detail"] for e in data["excluded"])
    assert {(e["a"], e["b"]) for e in data["watched"]} == watched
    back, _ = load_pairs(path)
    assert set(back.watched) == watched and len(back.excluded) == len(found.excluded)


def test_scenario_pairs_are_cached_in_the_results_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import reachwise.sim.self_pairs as sp

    r = _stick_robot()
    clouds = reachwise.link_clouds(r, points=100)
    home = np.zeros(r.n)
    first = sp.auto_self_pairs(r, clouds, 0.05, home=home, samples=200, cache_dir=tmp_path)
    file = tmp_path / "self-pairs-sticks.yaml"
    assert file.is_file()
    sp._MEMORY.clear()

    def boom(*args: object, **kwargs: object) -> None:
        raise AssertionError("computed again")

    monkeypatch.setattr(sp, "self_collision_pairs", boom)
    again = sp.auto_self_pairs(r, clouds, 0.05, home=home, samples=200, cache_dir=tmp_path)
    assert again.watched == first.watched
    with pytest.raises(AssertionError, match="computed again"):  # another margin: not cached
        sp.auto_self_pairs(r, clouds, 0.06, home=home, samples=200, cache_dir=tmp_path)


def _kd_distances(
    robot: Robot, clouds: dict[str, PointCloud], a: str, b: str, Q: np.ndarray
) -> np.ndarray:
    """The cloud distance of links ``a``, ``b`` at each configuration, by k-d tree."""
    F = robot.fk_all(Q)
    ia, ib = robot.link_index(a), robot.link_index(b)
    out = np.empty(len(Q))
    for s in range(len(Q)):
        pa = clouds[a].points @ F[s, ia, :3, :3].T + F[s, ia, :3, 3]
        pb = clouds[b].points @ F[s, ib, :3, :3].T + F[s, ib, :3, 3]
        out[s] = cKDTree(pb).query(pa)[0].min()
    return out


@needs_erd
def test_ur5_wrist_pairs_always_within_2cm_are_excluded_as_always(tmp_path: Path) -> None:
    """At a 2 cm margin the UR5's wrist_1-wrist_3 pair (among others) is within it in
    (nearly) every configuration: excluded as ``always``, with its clearance band, in
    the file and the SRDF (MoveIt's ``Always``), or, as its default clouds (1 cm
    coverage each) come within their resolutions, watched with a margin of its own.
    Distances are conservative by the clouds' resolutions: within the margin means
    within 2 cm + both resolutions between the clouds. Checked on a separate sample set
    by k-d tree: each excluded pair is within that in at least 95 % of it; and every
    watched pair leaves its own margin (plus the resolutions) somewhere (it could never
    be excluded as ``always``)."""
    from reachwise.io.srdf import read_srdf, write_srdf

    robot = reachwise.load_robot(arm_path("ur5"), tip="tool0")
    clouds = reachwise.link_clouds(robot)  # the default clouds (1 cm coverage)
    found = self_collision_pairs(robot, clouds, 0.02, samples=4000, seed=0)
    always = {(p.a, p.b) for p in found.always}
    own = {(p.a, p.b) for p in found.pairs if p.margin is not None}
    assert ("wrist_1_link", "wrist_3_link") in always | own
    assert all("always within 0.02 m" in p.detail and "clearance" in p.detail
               for p in found.always)  # fmt: skip
    assert all("its own margin" in p.detail for p in found.pairs if p.margin is not None)
    Q = random_configurations(robot, 400, 99)

    def coverage(a: str, b: str) -> float:
        return clouds[a].resolution + clouds[b].resolution

    for a, b in always:
        d = _kd_distances(robot, clouds, a, b, Q)
        assert np.mean(d <= 0.02 + coverage(a, b)) >= ALWAYS_FRACTION, (a, b)
    for (a, b), m in found.margins.items():
        d = _kd_distances(robot, clouds, a, b, Q)
        assert np.mean(d <= m + coverage(a, b)) < ALWAYS_FRACTION, (a, b)
    data = yaml.safe_load(save_pairs(found, tmp_path / "p.yaml").read_text())
    assert {(e["a"], e["b"]) for e in data["excluded"] if e["rule"] == "always"} == always
    assert "always" in data["rules"]
    srdf = read_srdf(write_srdf(found, tmp_path / "ur5.srdf"))
    assert {(p.link1, p.link2) for p in srdf.disabled if p.reason == "Always"} == always


def test_always_needs_the_share_of_samples_within_the_margin() -> None:
    """The ``always`` test against a pair whose distance is known at each sample: a
    query that answers from a table, 96 of 100 samples within the margin (always), then
    6 of 100 beyond it (not)."""
    from reachwise.distance.self_pairs import always_within

    class Table:
        margin = 0.02

        def __init__(self, d: np.ndarray) -> None:
            self.d = d

        def __call__(self, Ta: np.ndarray, Tb: np.ndarray) -> object:
            s = int(Ta[0, 0])
            near = self.d[s] <= self.margin

            class R:
                no_risk = not near
                distance = float(self.d[s]) if near else np.inf

            return R()

    F = np.zeros((100, 2, 4, 4))
    F[:, 0, 0, 0] = np.arange(100)
    d = np.full(100, 0.015)
    d[:4] = 0.03
    d[50] = 0.004
    got = always_within(Table(d), F, 0, 1, np.zeros(100))  # type: ignore[arg-type]
    assert got is not None and got[0] == pytest.approx(0.96)
    assert got[1] == pytest.approx(0.004) and got[2] == pytest.approx(0.02)
    d[4:6] = 0.05
    assert always_within(Table(d), F, 0, 1, np.zeros(100)) is None  # type: ignore[arg-type]
    assert always_within(Table(d * 0), F, 0, 1, np.full(100, 0.03)) is None  # type: ignore[arg-type]
