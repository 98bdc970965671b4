"""The TF tree: lookups along the tree against composed world poses, slerp + lerp in
time against the analytic in-between pose, and the errors of a missing path or time."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from reachwise.errors import InputError
from reachwise.io.ros.transform_tree import TransformTree


def _pose(rng: np.random.Generator) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-2, 2, 3)
    return T


def _add(
    tree: TransformTree, parent: str, child: str, t: float, T: np.ndarray, static: bool = False
) -> None:
    tree.add(parent, child, t, T[:3, 3], Rotation.from_matrix(T[:3, :3]).as_quat(), static=static)


@settings(max_examples=60, deadline=None)
@given(n=st.integers(2, 8), seed=st.integers(0, 2**32 - 1))
def test_lookup_along_a_random_tree_equals_composed_world_poses(n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    world = {"f0": np.eye(4)}
    tree = TransformTree()
    for i in range(1, n):
        parent = f"f{rng.integers(0, i)}"
        local = _pose(rng)
        world[f"f{i}"] = world[parent] @ local
        _add(tree, parent, f"f{i}", 0.0, local, static=bool(rng.integers(0, 2)))
        if not tree._edges[f"f{i}"].static:
            _add(tree, parent, f"f{i}", 1.0, local)
    for _ in range(5):
        a, b = (f"f{k}" for k in rng.integers(0, n, 2))
        expected = np.linalg.inv(world[a]) @ world[b]
        np.testing.assert_allclose(tree.lookup(a, b, 0.5), expected, atol=1e-9)


def test_interpolation_is_slerp_and_lerp() -> None:
    tree = TransformTree()
    T0, T1 = np.eye(4), np.eye(4)
    T1[:3, :3] = Rotation.from_rotvec([0, 0, 2.0]).as_matrix()
    T1[:3, 3] = [1.0, -2.0, 4.0]
    _add(tree, "world", "cam", 10.0, T0)
    _add(tree, "world", "cam", 12.0, T1)
    for s in (0.0, 0.25, 0.5, 1.0):
        T = tree.lookup("world", "cam", 10.0 + 2.0 * s)
        np.testing.assert_allclose(
            T[:3, :3], Rotation.from_rotvec([0, 0, 2.0 * s]).as_matrix(), atol=1e-12
        )
        np.testing.assert_allclose(T[:3, 3], [s, -2.0 * s, 4.0 * s], atol=1e-12)


def test_slerp_takes_the_shorter_arc_whatever_the_quaternion_sign() -> None:
    tree = TransformTree()
    q1 = Rotation.from_rotvec([0, 0, 0.4]).as_quat()
    tree.add("w", "c", 0.0, [0, 0, 0], [0, 0, 0, 1])
    tree.add("w", "c", 1.0, [0, 0, 0], -q1)  # the same rotation, the other sign
    T = tree.lookup("w", "c", 0.5)
    np.testing.assert_allclose(T[:3, :3], Rotation.from_rotvec([0, 0, 0.2]).as_matrix(), atol=1e-12)


def test_inverse_lookup() -> None:
    rng = np.random.default_rng(3)
    tree = TransformTree()
    _add(tree, "a", "b", 0.0, _pose(rng), static=True)
    _add(tree, "a", "c", 0.0, _pose(rng), static=True)
    np.testing.assert_allclose(
        tree.lookup("b", "c", 5.0) @ tree.lookup("c", "b", 5.0), np.eye(4), atol=1e-12
    )


def test_missing_path_names_both_frames_and_the_time() -> None:
    tree = TransformTree()
    _add(tree, "world", "cam", 0.0, np.eye(4), static=True)
    _add(tree, "base", "tool", 0.0, np.eye(4), static=True)
    with pytest.raises(InputError, match="no path between frames 'world' and 'tool'") as info:
        tree.lookup("world", "tool", 3.25)
    assert "t = 3.250000000 s" in str(info.value)
    with pytest.raises(InputError, match="nowhere"):
        tree.lookup("nowhere", "cam", 0.0)


def test_no_extrapolation_beyond_the_stamps_except_within_tolerance() -> None:
    tree = TransformTree()
    _add(tree, "w", "c", 1.0, np.eye(4))
    _add(tree, "w", "c", 2.0, np.eye(4))
    with pytest.raises(InputError, match=r"w -> c.*not known.*1\.0+ s to 2\.0+ s"):
        tree.lookup("w", "c", 2.5)
    loose = TransformTree(tolerance=0.6)
    _add(loose, "w", "c", 1.0, np.eye(4))
    _add(loose, "w", "c", 2.0, np.eye(4))
    np.testing.assert_array_equal(loose.lookup("w", "c", 2.5), np.eye(4))


def test_a_second_parent_and_a_loop_are_errors() -> None:
    tree = TransformTree()
    _add(tree, "a", "b", 0.0, np.eye(4))
    with pytest.raises(InputError, match="already has"):
        _add(tree, "x", "b", 0.0, np.eye(4))
    _add(tree, "b", "c", 0.0, np.eye(4))
    with pytest.raises(InputError, match="loop"):
        _add(tree, "c", "a", 0.0, np.eye(4))


def test_tf_message() -> None:
    from types import SimpleNamespace as N

    ts = N(
        header=N(stamp=N(sec=3, nanosec=500_000_000), frame_id="/map"),
        child_frame_id="base",
        transform=N(translation=N(x=1.0, y=2.0, z=3.0), rotation=N(x=0.0, y=0.0, z=0.0, w=1.0)),
    )
    tree = TransformTree()
    tree.add_message(N(transforms=[ts]), static=True)
    assert tree.lookup("map", "base", 99.0)[:3, 3].tolist() == [1.0, 2.0, 3.0]
