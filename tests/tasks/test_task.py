"""TaskPoint and Task: validation, inferred task-space size, poses and vectorized views."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from reachwise.errors import TaskError
from reachwise.tasks import Task, TaskPoint, TunnelEnvelope, TunnelProfile, frame_from_axis
from reachwise.tasks.task import PointArrays


def mixed_task() -> Task:
    R = Rotation.from_euler("xyz", [0.1, 0.2, 0.3]).as_matrix()
    return Task(
        "mixed",
        (
            TaskPoint(np.array([6.0, 0.5, 1.8]), rotation=R, name="a", group="cut"),
            TaskPoint(np.array([6.0, 1.0, 2.4]), axis=np.array([2.0, 0.0, 0.0]), group="cut"),
            TaskPoint(np.array([6.0, 1.5, 3.0]), tol_position=0.01, group="contour"),
        ),
    )


def test_dims_are_inferred_from_what_is_given() -> None:
    t = mixed_task()
    assert t.dims.tolist() == [6, 5, 3]
    assert np.allclose(t[1].axis, [1, 0, 0])  # normalized
    assert np.allclose(t[0].axis, t[0].rotation[:, 2])  # 6-D: axis is the z column


def test_poses_of_every_kind_are_rigid_and_match_the_point() -> None:
    t = mixed_task()
    T = t.poses
    assert T.shape == (3, 4, 4)
    for i, p in enumerate(t):
        assert np.allclose(T[i], p.pose)
        R = T[i, :3, :3]
        assert np.allclose(R.T @ R, np.eye(3)) and np.isclose(np.linalg.det(R), 1.0)
        assert np.allclose(T[i, :3, 3], p.position)
    assert np.allclose(T[0, :3, :3], t[0].rotation)
    assert np.allclose(T[2, :3, :3], np.eye(3))  # 3-D, nothing given
    # drilling straight ahead: z forward, y left, x down, i.e. Ry(90°)
    assert np.allclose(T[1, :3, :3], Rotation.from_euler("y", 90, degrees=True).as_matrix())


def test_vectorized_accessors() -> None:
    t = mixed_task()
    assert len(t) == 3 and t.positions.shape == (3, 3) and t.axes.shape == (3, 3)
    assert np.allclose(t.tol_position, [1e-3, 1e-3, 1e-2])
    assert np.allclose(t.tol_orientation, 1e-3)
    assert t.groups == ("cut", "cut", "contour") and t.names == ("a", "", "")
    gi = t.group_indices()
    assert list(gi) == ["cut", "contour"] and gi["cut"].tolist() == [0, 1]
    with pytest.raises(ValueError):
        t.positions[0, 0] = 1.0  # read-only views of a frozen task
    assert "3 points" in repr(t)


def test_subset_by_indices_and_mask() -> None:
    env = TunnelEnvelope(TunnelProfile(6, 5, 1.5))
    t = Task("t", mixed_task().points, env)
    s = t.subset([2, 0])
    assert s.dims.tolist() == [3, 6] and s.envelope is env and s.name == "t"
    m = t.subset(np.array([True, False, True]), name="two")
    assert len(m) == 2 and m.name == "two"
    with pytest.raises(TaskError, match="out of range"):
        t.subset([5])
    with pytest.raises(TaskError, match="empty task"):
        t.subset([], name="none")


@pytest.mark.parametrize(
    ("kwargs", "field", "reason"),
    [
        ({"position": [1.0, np.nan, 0.0]}, "position", "NaN"),
        ({"position": [1.0, 2.0]}, "position", "3 values"),
        ({"axis": [0.0, 0.0, 0.0]}, "axis", "zero-length"),
        ({"axis": [1.0, np.inf, 0.0]}, "axis", "NaN or inf"),
        ({"rotation": np.diag([1.0, 1.0, -1.0])}, "rotation", "proper rotation"),
        ({"rotation": np.eye(3) * 1.1}, "rotation", "proper rotation"),
        ({"dims": 6}, "dims", "needs an orientation"),
        ({"dims": 6, "axis": [1.0, 0.0, 0.0]}, "dims", "needs an orientation"),
        ({"dims": 5}, "dims", "needs a tool axis"),
        ({"dims": 4}, "dims", "3, 5 or 6"),
        ({"tol_position": 0.0}, "tol_position", "> 0"),
        ({"tol_orientation": -1e-3}, "tol_orientation", "> 0"),
        ({"tol_position": np.nan}, "tol_position", "> 0"),
        ({"rotation": np.eye(3), "axis": [1.0, 0.0, 0.0]}, "axis", "disagrees"),
    ],
)
def test_invalid_points_name_the_field(kwargs: dict, field: str, reason: str) -> None:
    args = {"position": [1.0, 2.0, 3.0], **kwargs}
    pos = args.pop("position")
    with pytest.raises(TaskError, match=reason) as info:
        TaskPoint(np.asarray(pos, dtype=float), **args)
    assert info.value.field == field


def test_task_needs_points_of_the_right_type() -> None:
    with pytest.raises(TaskError, match="empty task"):
        Task("empty", ())
    with pytest.raises(TaskError, match="not a TaskPoint") as info:
        Task("bad", (TaskPoint(np.zeros(3)), "x"))  # type: ignore[arg-type]
    assert info.value.field == "points[1]"


def test_from_arrays_tags_errors_with_the_point_index() -> None:
    P = np.zeros((4, 3))
    A = np.tile([1.0, 0.0, 0.0], (4, 1))
    A[2] = 0.0
    with pytest.raises(TaskError, match="zero-length") as info:
        Task.from_arrays("t", P, axes=A)
    assert info.value.field == "points[2].axis"
    t = Task.from_arrays("t", P, axes=np.tile([0.0, 0.0, 3.0], (4, 1)), tol_position=[1, 2, 3, 4])
    assert t.dims.tolist() == [5] * 4 and t.tol_position.tolist() == [1, 2, 3, 4]
    with pytest.raises(TaskError, match="empty task"):
        Task.from_arrays("t", np.zeros((0, 3)))
    with pytest.raises(TaskError, match="expected 4 entries"):
        Task.from_arrays("t", P, names=["a"])


unit_vectors = st.tuples(*[st.floats(-1, 1, allow_nan=False)] * 3).filter(
    lambda v: np.linalg.norm(v) > 1e-3
)


@settings(max_examples=200, deadline=None)
@given(unit_vectors, st.floats(-np.pi, np.pi))
def test_frame_from_axis_is_a_rotation_with_z_along_the_axis(v: tuple, roll: float) -> None:
    a = np.array(v) / np.linalg.norm(v)
    R = frame_from_axis(a, roll)
    assert np.allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.isclose(np.linalg.det(R), 1.0)
    assert np.allclose(R[:, 2], a, atol=1e-12)
    # roll turns the frame about its own z axis
    R0 = frame_from_axis(a)
    assert np.allclose(R0.T @ R, Rotation.from_euler("z", roll).as_matrix(), atol=1e-9)


def test_frame_from_axis_is_batched_and_handles_vertical_axes() -> None:
    A = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, 0, -1.0], [0.3, -0.2, 0.9]])
    R = frame_from_axis(A, np.array([0.0, 0.1, 0.2, 0.3]))
    assert R.shape == (4, 3, 3)
    for i in range(4):
        assert np.allclose(R[i], frame_from_axis(A[i], [0.0, 0.1, 0.2, 0.3][i]))
        assert np.isclose(np.linalg.det(R[i]), 1.0)


def test_from_arrays_takes_the_per_point_fields_as_a_group_or_as_keywords() -> None:
    P = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    group = PointArrays(axes=[0.0, 0.0, 2.0], tol_position=[0.01, 0.02], names=["a", "b"])
    by_group = Task.from_arrays("t", P, arrays=group)
    by_keywords = Task.from_arrays(
        "t", P, axes=[0.0, 0.0, 2.0], tol_position=[0.01, 0.02], names=["a", "b"]
    )
    assert by_group.dims.tolist() == by_keywords.dims.tolist() == [5, 5]
    assert np.array_equal(by_group.tol_position, [0.01, 0.02])
    assert [p.name for p in by_group] == [p.name for p in by_keywords] == ["a", "b"]
    # a keyword beside the group overrides its field
    assert Task.from_arrays("t", P, arrays=group, dims=3).dims.tolist() == [3, 3]
    with pytest.raises(TaskError, match="expected 2 entries") as info:
        Task.from_arrays("t", P, arrays=group, groups=["g"])
    assert info.value.field == "groups"
