"""Kinematics: the robot model, forward kinematics, Jacobians, IK and indices (pure math)."""

from reachwise.kinematics.ik import IKResult
from reachwise.kinematics.indices import condition_number, gci, kci, lci, manipulability
from reachwise.kinematics.orientation import axis_error, quaternion_error, rotation_error
from reachwise.kinematics.robot import DesignSpace, Joint, LinkGeometry, Robot

__all__ = [
    "DesignSpace",
    "IKResult",
    "Joint",
    "LinkGeometry",
    "Robot",
    "axis_error",
    "condition_number",
    "gci",
    "kci",
    "lci",
    "manipulability",
    "quaternion_error",
    "rotation_error",
]
