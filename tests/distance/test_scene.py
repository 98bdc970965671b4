"""The distance scene: pose sources, pair rules, query_all (P-IV/P-V collision server)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pytest
from numpy.typing import ArrayLike, NDArray

from reachwise import PointCloud
from reachwise.distance import PairQuery, Scene, closest_points
from reachwise.distance.index import INDICES
from reachwise.distance.scene import RobotLike
from reachwise.errors import InputError, NameTaken, UnknownName


def _rz(q: float) -> NDArray[np.float64]:
    c, s = math.cos(q), math.sin(q)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    return T


def _tx(x: float) -> NDArray[np.float64]:
    T = np.eye(4)
    T[0, 3] = x
    return T


@dataclass(frozen=True)
class FakeChain:
    """A planar chain of revolute joints about z, links of length ``lengths`` along x."""

    name: str
    lengths: tuple[float, ...]
    base: NDArray[np.float64] = field(default_factory=lambda: np.eye(4))

    @property
    def link_names(self) -> tuple[str, ...]:
        n = len(self.lengths)
        return ("link_0", *(f"link_{i}" for i in range(1, n + 1)), "tool")

    def fk_all(self, q: ArrayLike) -> NDArray[np.float64]:
        q = np.asarray(q, dtype=np.float64)
        frames = [self.base]
        T = self.base
        for i in range(len(self.lengths)):
            T = T @ (_tx(self.lengths[i - 1]) if i else np.eye(4)) @ _rz(q[i])
            frames.append(T)
        frames.append(T @ _tx(self.lengths[-1]))
        return np.stack(frames)


def _rod(length: float, n: int = 40) -> NDArray[np.float64]:
    """Points along a link from its frame origin to x = length, with some girth."""
    rng = np.random.default_rng(n)
    x = np.linspace(0.0, length, n)
    return np.column_stack([x, rng.uniform(-0.02, 0.02, n), rng.uniform(-0.02, 0.02, n)])


def _robot_scene(q: ArrayLike) -> tuple[Scene, FakeChain]:
    robot = FakeChain("arm", (0.5, 0.4, 0.3, 0.2))
    scene = Scene()
    scene.add_robot(robot, q)
    for i, L in enumerate(robot.lengths, start=1):
        scene.add_object(f"arm/link_{i}", _rod(L), robot="arm", link=f"link_{i}")
    scene.add_object("arm/base", _rod(0.1), robot="arm", link="link_0")
    scene.add_object("arm/tool", _rod(0.05), robot="arm", link="tool")
    return scene, robot


def test_fake_chain_satisfies_the_robot_protocol() -> None:
    assert isinstance(FakeChain("x", (1.0,)), RobotLike)


def test_real_robot_drives_a_scene(rng: np.random.Generator) -> None:
    conftest = pytest.importorskip("tests.conftest")
    robot = conftest.random_chain(rng, n_joints=5)
    assert isinstance(robot, RobotLike)
    n_q = sum(j.type != "fixed" for j in robot.joints) if hasattr(robot, "joints") else 5
    q = rng.uniform(-1.0, 1.0, n_q)
    scene = Scene()
    scene.add_robot(robot, q)
    names = robot.link_names
    for link in names:
        scene.add_object(link, _rod(0.3), robot=robot.name, link=link)
    scene.watch_self(robot.name, math.inf)
    frames = robot.fk_all(q)
    for p in scene.query_all().pairs:
        ref = closest_points(
            scene.objects[p.a].cloud,
            scene.objects[p.b].cloud,
            frames[names.index(p.a)],
            frames[names.index(p.b)],
            strategy="brute",
        )
        assert p.result.distance == pytest.approx(ref.distance, abs=1e-9)


def test_self_pairs_skip_same_and_adjacent_links_and_exclusions() -> None:
    scene, _ = _robot_scene(np.zeros(4))
    pairs = scene.watch_self("arm", 0.1, exclude=[("link_1", "link_3")])
    names = {frozenset((p.a, p.b)) for p in pairs}
    assert frozenset(("arm/link_1", "arm/link_3")) not in names  # excluded
    assert frozenset(("arm/link_1", "arm/link_2")) not in names  # adjacent
    assert frozenset(("arm/link_4", "arm/tool")) not in names  # adjacent
    assert frozenset(("arm/base", "arm/link_1")) not in names  # adjacent
    assert frozenset(("arm/base", "arm/link_2")) in names
    assert frozenset(("arm/link_1", "arm/link_4")) in names
    assert frozenset(("arm/link_2", "arm/tool")) in names
    assert all(p.kind == "self" and p.margin == 0.1 for p in pairs)
    # every pair of links at least two apart in link_names, minus the exclusion
    assert len(pairs) == 15 - 5 - 1


def test_query_all_matches_closest_points_at_the_link_poses() -> None:
    q = np.array([0.3, 2.6, 2.5, -0.4])  # folded back on itself
    scene, robot = _robot_scene(q)
    env = np.random.default_rng(1).uniform([-1, -1, -0.3], [1, 1, -0.25], (500, 3))
    scene.add_object("floor", env)
    scene.add_object("crate", _rod(0.3), pose=_tx(0.6), dynamic=True)
    scene.watch_self("arm", 0.3)
    scene.watch_environment("arm", 0.5)
    res = scene.query_all()
    assert res.sequence == 1
    frames = robot.fk_all(q)
    index = {n: i for i, n in enumerate(robot.link_names)}
    objects = scene.objects
    for p in res.pairs:
        oa, ob = objects[p.a], objects[p.b]

        def pose_of(o):  # type: ignore[no-untyped-def]
            src = o.source
            if hasattr(src, "link"):
                return frames[index[src.link]] @ src.offset
            return src.pose if hasattr(src, "pose") else _tx(0.6)

        ref = closest_points(
            oa.cloud, ob.cloud, pose_of(oa), pose_of(ob), p.margin, strategy="brute"
        )
        assert p.result.no_risk == ref.no_risk
        if not ref.no_risk:
            assert p.result.distance == pytest.approx(ref.distance, abs=1e-12)
    assert res.at_risk()  # the folded arm is close to itself
    d = [p.result.distance for p in res.at_risk()]
    assert d == sorted(d)
    # pairs of the crate follow its run-time pose
    before = res.get("arm/link_1", "crate").result
    scene.set_pose("crate", _tx(5.0))
    res2 = scene.query_all()
    assert res2.sequence == 2
    assert res2.get("crate", "arm/link_1").result.no_risk
    if not before.no_risk:
        swapped = res.get("crate", "arm/link_1").result
        np.testing.assert_allclose(swapped.direction, -before.direction)
    with pytest.raises(UnknownName, match=r"unknown watched pair '\(crate, floor\)'"):
        res.get("crate", "floor")


def test_joint_state_moves_the_link_objects() -> None:
    scene, robot = _robot_scene(np.zeros(4))
    scene.add_object("post", np.array([[0.5, 0.3, 0.0]]))
    scene.watch("arm/link_2", "post", math.inf)
    d0 = scene.query_all().get("arm/link_2", "post").result.distance
    scene.set_joints("arm", [0.6, 0.0, 0.0, 0.0])
    d1 = scene.query_all().get("arm/link_2", "post").result.distance
    assert d1 != pytest.approx(d0)
    ref = closest_points(
        scene.objects["arm/link_2"].cloud,
        np.array([[0.5, 0.3, 0.0]]),
        robot.fk_all([0.6, 0.0, 0.0, 0.0])[2],
        strategy="brute",
    )
    assert d1 == pytest.approx(ref.distance, abs=1e-12)


def test_robot_robot_pairs() -> None:
    scene, _ = _robot_scene(np.zeros(4))
    other = FakeChain("arm2", (0.5, 0.5), base=_tx(1.2) @ _rz(math.pi))
    scene.add_robot(other, [0.1, -0.2])
    scene.add_object("arm2/link_1", _rod(0.5), robot="arm2", link="link_1")
    scene.add_object("arm2/link_2", _rod(0.5), robot="arm2", link="link_2")
    pairs = scene.watch_robots("arm", "arm2", 0.4)
    assert len(pairs) == 6 * 2 and all(p.kind == "robot-robot" for p in pairs)
    res = scene.query_all()
    assert len(res.pairs) == 12


def test_replace_cloud_rebuilds_and_answers_with_the_new_cloud() -> None:
    scene = Scene()
    scene.add_object("part", np.zeros((1, 3)), dynamic=True)
    scene.add_object("env", np.array([[0.0, 0.0, 1.0]]))
    scene.watch("part", "env", 2.0)
    assert scene.query_all().pairs[0].result.distance == pytest.approx(1.0)
    new = PointCloud(np.array([[0.0, 0.0, 0.25], [3.0, 0.0, 0.0]]), name="rescan")
    scene.replace_cloud("env", new, block=True)
    assert INDICES.peek(new) is not None  # indexed at once
    r = scene.query_all().pairs[0].result
    assert r.distance == pytest.approx(0.25) and r.index_b == 0


def test_scene_with_other_strategies_agrees() -> None:
    q = np.array([0.3, 2.6, 2.5, -0.4])
    results = {}
    for s in ("default", "thesis", "brute"):
        scene = Scene(strategy=s)
        robot = FakeChain("arm", (0.5, 0.4, 0.3, 0.2))
        scene.add_robot(robot, q)
        for i, L in enumerate(robot.lengths, start=1):
            scene.add_object(f"l{i}", _rod(L), robot="arm", link=f"link_{i}")
        scene.watch_self("arm", 0.3)
        results[s] = [(p.result.no_risk, p.result.distance) for p in scene.query_all().pairs]
    for s in ("thesis", "brute"):
        for (nr1, d1), (nr2, d2) in zip(results["default"], results[s], strict=True):
            assert nr1 == nr2 and (nr1 or abs(d1 - d2) <= 1e-9)


def test_scene_errors() -> None:
    scene = Scene()
    with pytest.raises(UnknownName, match="unknown strategy 'nope'; valid: brute, default, thesis"):
        Scene(strategy="nope")  # type: ignore[arg-type]
    with pytest.raises(UnknownName, match="unknown robot 'ghost'; there are none"):
        scene.add_object("x", np.zeros((1, 3)), robot="ghost", link="link_0")
    robot = FakeChain("arm", (0.5,))
    scene.add_robot(robot)
    with pytest.raises(NameTaken, match="already registered"):
        scene.add_robot(robot)
    with pytest.raises(UnknownName, match="'arm': link: unknown link 'link_9'; valid: link_0, "):
        scene.add_object("x", np.zeros((1, 3)), robot="arm", link="link_9")
    scene.add_object("x", np.zeros((1, 3)), robot="arm", link="link_1")
    scene.add_object("y", np.ones((1, 3)))
    with pytest.raises(NameTaken, match="already exists") as taken:
        scene.add_object("y", np.ones((1, 3)))
    assert isinstance(taken.value, InputError) and taken.value.field == "name"
    with pytest.raises(InputError, match="not set at run time"):
        scene.set_pose("y", np.eye(4))
    with pytest.raises(UnknownName, match="unknown object 'z'; valid: x, y"):
        scene.watch("x", "z", 0.1)
    with pytest.raises(UnknownName, match="unknown pair kind 'near'; valid: custom, robot-"):
        scene.watch("x", "y", 0.1, kind="near")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="itself"):
        scene.watch("x", "x", 0.1)
    with pytest.raises(InputError, match="margin"):
        scene.watch("x", "y", -1.0)
    scene.watch("x", "y", 0.1)
    with pytest.raises(InputError, match="no joint state"):
        scene.query_all()
    with pytest.raises(InputError, match="NaN"):
        scene.set_joints("arm", [np.nan])
    scene.set_joints("arm", [0.0])
    assert scene.query_all().sequence == 1
    scene.unwatch("y", "x")
    assert scene.query_all().pairs == ()


def test_an_added_clouds_stamp_is_its_measurement_time() -> None:
    """``add_object``'s ``stamp``: +inf by default (does not age), NaN (unknown) or a
    time, carried by the answers' ``cloud_stamps`` until a new cloud replaces it; a
    stamp that is no time, inf or NaN is refused."""
    scene = Scene()
    scene.add_object("cad", np.zeros((1, 3)))
    scene.add_object("seen", np.ones((1, 3)), stamp=math.nan)
    scene.add_object("scan", np.ones((1, 3)), stamp=2.5)
    stamps = scene.query_all().cloud_stamps
    assert stamps["cad"] == math.inf and math.isnan(stamps["seen"]) and stamps["scan"] == 2.5
    scene.replace_cloud("seen", np.ones((2, 3)), block=True, stamp=3.0)
    assert scene.query_all().cloud_stamps["seen"] == 3.0
    for bad in (-math.inf, "now", True):
        with pytest.raises(InputError, match="stamp"):
            scene.add_object("bad", np.zeros((1, 3)), stamp=bad)  # type: ignore[arg-type]
    assert "bad" not in scene.objects
    scene.close()


@pytest.mark.parametrize("larger", ["a", "b"])
def test_pair_query_used_by_the_scene_is_warm_started(larger: str) -> None:
    """An exact tie shows the warm start: two points of one cloud at exactly the same
    distance from the other cloud's point. The search only replaces its best pair by a
    strictly closer one, so a warm query keeps the pair it brought from the previous
    query, and which tied pair it reports depends on the history: the one it came from.
    A cold query (after ``reset``, or a fresh ``PairQuery``) has no history and always
    gives the same answer. The distance is exact either way."""
    far = np.random.default_rng(0).uniform(-1, 1, (200, 3)) + np.array([0.0, 0.0, -5.0])
    twins = PointCloud(np.vstack([[[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]], far]))
    probe = PointCloud(np.array([[0.0, 0.0, 0.0]]))

    def at(x: float) -> np.ndarray:
        T = np.eye(4)
        T[0, 3], T[2, 3] = x, 2.0
        return T

    def query(pq: PairQuery, x: float) -> tuple[int, float]:
        """The twin reported with the probe at (x, 0, 2), and the distance."""
        if larger == "a":
            r = pq(np.eye(4), at(x))
            return r.index_a, r.distance
        r = pq(at(x), np.eye(4))
        return r.index_b, r.distance

    def make() -> PairQuery:
        return PairQuery(twins, probe) if larger == "a" else PairQuery(probe, twins)

    tie = math.sqrt(5.0)  # both twins are sqrt(1 + 4) from the probe at x = 0
    cold, d = query(make(), 0.0)
    assert d == tie
    pq = make()
    for came_from, twin in ((-0.5, 0), (0.5, 1), (-0.5, 0)):
        assert query(pq, came_from)[0] == twin  # unique nearest twin
        assert query(pq, 0.0) == (twin, tie)  # the tie resolved by the history
    # the same query (probe at x = 0) answered with both twins: only a warm start can
    # do that; a cold query gives one of them every time
    pq.reset()
    assert query(pq, 0.0) == (cold, tie)


def test_clear_empties_the_scene_and_drops_clouds_handed_over_before() -> None:
    """After ``clear`` the scene answers as a new one built the same way; a cloud
    handed over before the clear is never swapped in, and the scene's memories go."""
    from reachwise.distance.scene_memories import add_memory, memories_of

    scene, robot = _robot_scene([0.3, 0.2, 0.1, 0.0])
    scene.add_object("env", np.array([[0.0, 0.0, 1.0]]))
    scene.watch_environment("arm", 5.0, ["env"])
    add_memory(scene, "seen", np.array([-1.0, -1.0, 0.0]), np.ones(3))
    scene.replace_cloud("env", np.array([[0.0, 0.0, 0.05]]))  # not swapped in yet
    scene.clear()
    assert scene.generation == 1
    assert (scene.objects, scene.robots, scene.pairs, dict(memories_of(scene))) == ({}, {}, (), {})
    q = np.array([0.5, -0.4, 0.2, 0.1])
    fresh, _ = _robot_scene(q)
    for s in (scene, fresh):
        if s is scene:
            s.add_robot(robot, q)
            for i, L in enumerate(robot.lengths, start=1):
                s.add_object(f"arm/link_{i}", _rod(L), robot="arm", link=f"link_{i}")
            s.add_object("arm/base", _rod(0.1), robot="arm", link="link_0")
            s.add_object("arm/tool", _rod(0.05), robot="arm", link="tool")
        s.add_object("env", np.array([[0.0, 0.0, 1.0]]))
        s.watch_environment("arm", 5.0, ["env"])
    got, want = scene.query_all(), fresh.query_all()
    assert got.versions == {name: 0 for name in scene.objects}
    assert [p.result.distance for p in got.pairs] == [p.result.distance for p in want.pairs]
    add_memory(scene, "seen", np.array([-1.0, -1.0, 0.0]), np.ones(3))  # its name is free again
    assert set(memories_of(scene)) == {"seen"}
    scene.close()
    fresh.close()
