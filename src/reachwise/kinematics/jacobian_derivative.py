"""How the tool Jacobian changes with the joint values and the design (P-I Eq. 15–19).

Every joint variable, DH parameter and base coordinate moves the chain by a unit screw:
the tool twist ``(v_s, ω_s)`` of parameter ``s`` is a column of the tool Jacobian (joint
variables) or of the DH-parameter Jacobian ``Robot.param_jacobian`` (P-I Eq. 15–19).
The geometric Jacobian's column ``i`` is ``[z_i × (p − o_i); z_i]`` (revolute) or
``[z_i; 0]`` (prismatic). A change of parameter ``s`` either

* moves joint ``i``'s axis with everything distal to it (``s`` lies between the base
  and the axis): the column turns rigidly, ``∂J_i/∂s = ω_s × J_i`` (both halves; for a
  revolute column this is ``(ω×z)×r + z×(ω×r) = ω×(z×r)`` with ``r = p − o_i``), or
* leaves the axis in place and moves only the tool point ``p`` by ``v_s``:
  ``∂J_i/∂s = [z_i × v_s; 0]`` for a revolute column, ``0`` for a prismatic one.

For modified DH (P-I Eq. 2–3) joint ``i``'s axis is ``z`` of frame ``i``: the ``a`` and
``alpha`` of its own row and every parameter of the rows before it move it, its own
``theta`` and ``d`` (along and about that axis) do not. For classic DH the axis is ``z``
of frame ``i − 1``: only rows before it move it. Base coordinates move every axis; a
joint variable moves the axes distal to it. These are the exact derivatives (tested
against central finite differences); the LCI gradient uses them (``conditioning``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import InputError
from reachwise.kinematics.jacobian import jacobians

if TYPE_CHECKING:
    from reachwise.kinematics.robot import Robot

Array = NDArray[np.float64]
_DH = ("a", "alpha", "d", "theta")
_BASE = ("x", "y", "z", "roll", "pitch", "yaw")


def parameter_columns(robot: Robot, params: Sequence[tuple[str, int, str]]) -> NDArray[np.int64]:
    """Columns of ``Robot.param_jacobian`` for parameters given as ``DesignSpace.free``
    entries ``("joint", row, name)`` or ``("base", -1, name)``."""
    N = len(robot.joints)
    cols = []
    for kind, j, p in params:
        if kind == "joint" and p in _DH and 0 <= j < N:
            cols.append(4 * j + _DH.index(p))
        elif kind == "base" and p in _BASE:
            cols.append(4 * N + _BASE.index(p))
        else:
            raise InputError(robot.name, "params", f"unknown parameter {(kind, j, p)!r}")
    return np.array(cols, dtype=np.int64)


def moves_axis(robot: Robot, params: Sequence[tuple[str, int, str]]) -> NDArray[np.bool_]:
    """``(n + s, n)``: does parameter ``k`` (joint variables first, then ``params``)
    move the axis of joint variable ``i``? (module docstring)."""
    rows = np.array(robot.movable_joints, dtype=np.int64)
    modified = robot.convention == "modified"
    out = np.zeros((robot.n + len(params), robot.n), dtype=np.bool_)
    out[: robot.n] = rows[:, None] < rows[None, :]
    for k, (kind, j, p) in enumerate(params):
        if kind == "base":
            out[robot.n + k] = True
        else:
            out[robot.n + k] = (j < rows) | ((j == rows) & modified & (p in ("a", "alpha")))
    return out


def jacobian_derivatives(
    robot: Robot, q: ArrayLike, params: Sequence[tuple[str, int, str]] = ()
) -> tuple[Array, Array, Array, Array]:
    """Tool poses, Jacobians, parameter twists and the Jacobian's derivatives.

    For a batch ``q (m, n)`` returns ``T (m, 4, 4)``, ``J (m, 6, n)``, the tool twists
    ``W (m, 6, n + s)`` of the joint variables and then of ``params`` (``s`` entries like
    ``DesignSpace.free``), and ``dJ (m, 6, n, n + s)`` with ``dJ[..., i, k] = ∂J_i/∂θ_k``.
    """
    Q = np.atleast_2d(np.asarray(q, dtype=np.float64))
    with_params = len(params) > 0
    T, J, P = jacobians(robot, Q, params=with_params)
    W = J
    if with_params:
        W = np.concatenate([J, P[:, :, parameter_columns(robot, params)]], axis=2)
    move = moves_axis(robot, params)  # (n + s, n)
    v = np.moveaxis(W[:, :3, :], 1, 2)[:, None, :, :]  # (m, 1, S, 3)
    w = np.moveaxis(W[:, 3:, :], 1, 2)[:, None, :, :]
    Jl = np.moveaxis(J[:, :3, :], 1, 2)[:, :, None, :]  # (m, n, 1, 3)
    Ja = np.moveaxis(J[:, 3:, :], 1, 2)[:, :, None, :]
    revolute = np.array([robot.joints[i].type == "revolute" for i in robot.movable_joints])
    rigid_l = np.cross(w, Jl)  # (m, n, S, 3): ω_s × J_i
    rigid_a = np.cross(w, Ja)
    tip_l = np.cross(Ja, v) * revolute[None, :, None, None]  # z_i × v_s
    mv = move.T[None, :, :, None]  # (1, n, S, 1)
    dl = np.where(mv, rigid_l, tip_l)
    da = np.where(mv, rigid_a, 0.0)
    dJ = np.concatenate([dl, da], axis=3)  # (m, n, S, 6)
    return T, J, W, np.ascontiguousarray(np.moveaxis(dJ, 3, 1))
