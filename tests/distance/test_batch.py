"""The scene's one compiled call for every pair: the same answers as a PairQuery per pair
(warm starts and all, number for number) and as brute force, on random scenes; the
answer rows and the PairResults made from them on demand."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from reachwise.distance import PairQuery, Scene
from reachwise.distance.answers import PairAnswers, rows_of
from reachwise.distance.scene import SceneResult
from reachwise.kinematics.robot import Joint, Robot


def _pose(rng: np.random.Generator, spread: float = 1.0) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng.integers(2**31)).as_matrix()
    T[:3, 3] = rng.uniform(-spread, spread, 3)
    return T


def _arm() -> Robot:
    """A small 3-joint arm (the scene's compiled forward kinematics path)."""
    joints = (
        Joint("revolute", a=0.0, alpha=0.0, d=0.3, theta=0.0, limits=(-3.0, 3.0)),
        Joint("revolute", a=0.0, alpha=-1.5708, d=0.0, theta=0.0, limits=(-3.0, 3.0)),
        Joint("revolute", a=0.5, alpha=0.0, d=0.0, theta=0.0, limits=(-3.0, 3.0)),
    )
    return Robot("arm", joints)


def _brute(a: np.ndarray, b: np.ndarray) -> tuple[float, int, int]:
    d2 = ((a[:, None, :] - b[None, :, :]) ** 2).sum(axis=2)
    i, j = np.unravel_index(int(np.argmin(d2)), d2.shape)
    return math.sqrt(float(d2[i, j])), int(i), int(j)


def _world(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    return np.asarray(points @ pose[:3, :3].T + pose[:3, 3])


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_batched_answers_equal_pair_queries_and_brute_force(seed: int) -> None:
    rng = np.random.default_rng(seed)
    robot = _arm()
    scene = Scene()
    scene.add_robot(robot, rng.uniform(-1, 1, robot.n))
    names = []
    for k in range(int(rng.integers(2, 6))):
        pts = rng.normal(scale=rng.uniform(0.02, 0.4), size=(int(rng.integers(1, 150)), 3))
        kind = rng.integers(3)
        name = f"o{k}"
        if kind == 0:
            scene.add_object(name, pts, _pose(rng))
        elif kind == 1:
            scene.add_object(name, pts, _pose(rng), dynamic=True)
        else:
            link = robot.link_names[int(rng.integers(len(robot.link_names)))]
            scene.add_object(name, pts, _pose(rng, 0.2), robot="arm", link=link)
        names.append(name)
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            if rng.uniform() < 0.8:
                margin = math.inf if rng.uniform() < 0.3 else float(rng.uniform(0.0, 2.0))
                scene.watch(a, b, margin)
    queries = {(p.a, p.b): PairQuery(scene.objects[p.a].cloud, scene.objects[p.b].cloud,
                                     margin=p.margin) for p in scene.pairs}  # fmt: skip
    for _ in range(4):  # moving poses: the warm starts of both sides must agree
        scene.set_joints("arm", rng.uniform(-1, 1, robot.n))
        for n in names:
            if scene.objects[n].source.__class__.__name__ == "Runtime":
                scene.set_pose(n, _pose(rng))
        poses = scene.poses()
        res = scene.query_all()
        assert isinstance(res.pairs, PairAnswers) and len(res.pairs) == len(scene.pairs)
        for p, row in zip(res.pairs, res.rows, strict=True):
            ref = queries[(p.a, p.b)](poses[p.a], poses[p.b])
            r = p.result
            assert r.no_risk == ref.no_risk
            if not r.no_risk:
                assert r.distance == ref.distance
                assert (r.index_a, r.index_b) == (ref.index_a, ref.index_b)
                np.testing.assert_array_equal(r.point_a, ref.point_a)
                np.testing.assert_array_equal(r.direction, ref.direction)
            A = _world(scene.objects[p.a].cloud.points, poses[p.a])
            B = _world(scene.objects[p.b].cloud.points, poses[p.b])
            d, _, _ = _brute(A, B)
            if r.no_risk:
                assert d > p.margin - 1e-9
                assert row[12] == 1.0 and math.isinf(row[0])
            else:
                assert r.distance == pytest.approx(d, abs=1e-9)
                np.testing.assert_allclose(r.point_a, A[r.index_a], atol=1e-12)
                np.testing.assert_allclose(r.point_b, B[r.index_b], atol=1e-12)
    scene.close()


def test_other_strategies_answer_the_same_pairs_in_the_same_rows(rng: np.random.Generator) -> None:
    scenes = {s: Scene(strategy=s) for s in ("default", "brute", "thesis")}
    a = rng.normal(scale=0.2, size=(120, 3))
    b = rng.normal(scale=0.3, size=(90, 3))
    c = rng.normal(scale=0.1, size=(60, 3))
    for s in scenes.values():
        s.add_object("a", a)
        s.add_object("b", b, _pose(np.random.default_rng(1), 0.6))
        s.add_object("c", c, dynamic=True)
        s.watch("a", "b", math.inf)
        s.watch("b", "c", 0.3)
        s.watch("a", "c", 1.0)
    for k in range(3):
        pose = _pose(np.random.default_rng(k + 10), 0.8)
        results = {}
        for name, s in scenes.items():
            s.set_pose("c", pose)
            results[name] = s.query_all()
        ref = results["brute"]
        for name, res in results.items():
            assert [(p.a, p.b) for p in res.pairs] == [(p.a, p.b) for p in ref.pairs]
            np.testing.assert_allclose(res.rows[:, 0], ref.rows[:, 0], atol=1e-12, err_msg=name)
            np.testing.assert_array_equal(res.rows[:, 12], ref.rows[:, 12])


def test_answer_rows_and_the_pair_results_made_from_them(rng: np.random.Generator) -> None:
    scene = Scene()
    scene.add_object("a", rng.normal(size=(50, 3)))
    scene.add_object("b", rng.normal(size=(40, 3)) + np.array([3.0, 0, 0]))
    scene.add_object("far", rng.normal(size=(30, 3)) + np.array([50.0, 0, 0]))
    scene.watch("a", "b", math.inf)
    scene.watch("a", "far", 1.0)
    res = scene.query_all()
    rows = res.rows
    assert rows.shape == (2, 13) and not rows.flags.writeable
    near, far = res.pairs
    assert res.pairs[0] is near  # made once, then kept
    assert far.result.no_risk and rows[1, 12] == 1.0 and rows[1, 10] == -1.0
    assert not near.result.no_risk and rows[0, 12] == 0.0
    assert near.result.distance == rows[0, 0]
    assert near.versions == (0, 0)
    # the rows of the PairResults (the form a remote answer comes in) are the same numbers
    np.testing.assert_array_equal(rows_of(tuple(res.pairs)), rows)
    assert res.pairs == tuple(res.pairs)
    plain = SceneResult(res.sequence, tuple(res.pairs))
    np.testing.assert_array_equal(plain.rows, rows)
    assert res.get("b", "a").result.distance == near.result.distance
    assert res.pairs[-1] is far and res.pairs[0:1] == (near,)
    with pytest.raises(IndexError):
        res.pairs[2]
    # a later query writes new rows and leaves this answer's alone
    again = scene.query_all()
    assert again.rows is not rows
    np.testing.assert_array_equal(rows[:, 0], again.rows[:, 0])
    scene.close()


def test_a_new_rule_keeps_the_other_pairs_warm_and_changes_the_rows(
    rng: np.random.Generator,
) -> None:
    scene = Scene()
    for n in "abc":
        scene.add_object(n, rng.normal(size=(80, 3)) + rng.uniform(-3, 3, 3), dynamic=True)
    scene.watch("a", "b", math.inf)
    first = scene.query_all()
    scene.watch("a", "c", math.inf)
    scene.watch("b", "c", 0.5)
    second = scene.query_all()
    assert [(p.a, p.b) for p in second.pairs] == [("a", "b"), ("a", "c"), ("b", "c")]
    assert second.rows[0, 0] == first.rows[0, 0]
    scene.unwatch("a", "b")
    third = scene.query_all()
    assert [(p.a, p.b) for p in third.pairs] == [("a", "c"), ("b", "c")]
    np.testing.assert_array_equal(third.rows, second.rows[1:])
    scene.close()
