"""JointState to q by name, never by index."""

from __future__ import annotations

from types import SimpleNamespace as N

import numpy as np
import pytest

import reachwise
from reachwise.io.ros.joint_state import JointMatcher, robot_joint_names
from reachwise.io.ros.recording_error import RecordingError
from reachwise.io.urdf import load_urdf
from tests._real_arms import arm_path, needs_erd
from tests.io.ros._messages import header


def _js(names: list[str], pos: list[float], t: float = 4.0) -> N:
    return N(header=header(t, ""), name=names, position=pos, velocity=[], effort=[])


def test_order_and_extra_joints_do_not_matter() -> None:
    m = JointMatcher(["j1", "j2", "j3"])
    q = m.positions(_js(["finger", "j3", "j1", "j2"], [9.0, 3.0, 1.0, 2.0]))
    assert q.tolist() == [1.0, 2.0, 3.0]
    q = m.positions(_js(["j2", "j1", "j3"], [20.0, 10.0, 30.0]))  # a new order
    assert q.tolist() == [10.0, 20.0, 30.0]


def test_missing_joint_names_topic_time_and_joint() -> None:
    m = JointMatcher(["j1", "j2"])
    with pytest.raises(RecordingError, match=r"/joint_states.*lacks.*'j2'.*t = 4\.0"):
        m.positions(_js(["j1", "other"], [1.0, 2.0]), topic="/joint_states")


def test_positions_shorter_than_names_is_an_error() -> None:
    with pytest.raises(RecordingError, match="position"):
        JointMatcher(["j1"]).positions(_js(["j1", "j2"], [1.0]))


def test_nan_position_is_an_error() -> None:
    with pytest.raises(RecordingError, match="not finite"):
        JointMatcher(["j1"]).positions(_js(["j1"], [np.nan]))


def test_unnamed_joints_are_named_after_the_robot() -> None:
    panda = reachwise.load_robot("panda")  # the built-in DH table names no joint
    assert robot_joint_names(panda) == tuple(f"panda_joint{k}" for k in range(1, 8))


@needs_erd
def test_urdf_joint_names() -> None:
    ur5 = load_urdf(arm_path("ur5"), tip="tool0")
    names = robot_joint_names(ur5)
    assert names[0] == "shoulder_pan_joint" and len(names) == ur5.n
