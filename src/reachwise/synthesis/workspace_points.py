"""Sampled link points of every task configuration and their Jacobians (P-II Eq. 29–33).

The workspace constraint (the tunnel walls, floor and roof) acts on points of the
manipulator's skeleton: the frame origins ``o_0 … o_{N+1}`` (base, every joint frame,
tool) and ``S`` points on each segment between consecutive origins. A point
``p = (1 − s) o_k + s o_{k+1}`` has the exact Jacobian ``(1 − s) J(o_k) + s J(o_{k+1})``.
Origin Jacobians use the same unit screws as ``Robot.param_jacobian``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from reachwise.kinematics.fk import fk_all

if TYPE_CHECKING:
    from reachwise.synthesis.problem import SynthesisProblem

Array = NDArray[np.float64]


def _screw_on_points(
    axis: Array, origin: Array, revolute: bool, pts: Array, mask: NDArray[np.bool_]
) -> Array:
    """Linear velocity of points ``pts (K, M, 3)`` for a unit screw; ``axis``/``origin``
    are ``(K, 3)``; columns where ``mask (M,)`` is False are 0."""
    if revolute:
        v = np.cross(axis[:, None, :], pts - origin[:, None, :])
    else:
        v = np.broadcast_to(axis[:, None, :], pts.shape).copy()
    v[:, ~mask] = 0.0
    return np.asarray(v)


def origin_jacobians(problem: SynthesisProblem, z: Array) -> tuple[Array, Array, Array]:
    """Frame origins ``(K, N+2, 3)`` and their Jacobians w.r.t. the design variables
    ``(K, N+2, 3, p)`` and the free joints ``(K, N+2, 3, n_f)``."""
    design, Q = problem.split(z)
    robot = problem.robot_at(design)
    F = np.asarray(fk_all(robot, Q))  # (K, N+2, 4, 4)
    O = F[:, :, :3, 3]
    frames = np.arange(F.shape[1])
    Jd, Jq = attached_point_jacobians(problem, F, frames, O)
    return O, Jd, Jq


def attached_point_jacobians(
    problem: SynthesisProblem, F: Array, frames: NDArray[np.int64], pts: Array
) -> tuple[Array, Array]:
    """Jacobians of world points ``pts (K, M, 3)`` rigidly attached to the frames
    ``frames (M,)`` (rows of ``fk_all``; ``F (K, N+2, 4, 4)`` the frames' world poses at
    the current design) w.r.t. the design variables ``(K, M, 3, p)`` and the free joints
    ``(K, M, 3, n_f)``: the unit screw of every joint variable, DH parameter and base
    coordinate (P-I Eq. 15–19) at each point, zero where it does not move the frame."""
    robot = problem.template
    K = F.shape[0]
    classic = robot.convention == "classic"
    Jq = np.zeros((K, pts.shape[1], 3, robot.n))
    for i, k in enumerate(robot.movable_joints):
        f = k if classic else k + 1
        mask = frames >= k + 1
        rev = robot.joints[k].type == "revolute"
        Jq[:, :, :, i] = _screw_on_points(F[:, f, :3, 2], F[:, f, :3, 3], rev, pts, mask)
    Jd = np.zeros((K, pts.shape[1], 3, problem.p))
    for c, (kind, j, par) in enumerate(robot.design.free):
        if kind == "joint":
            P, C = F[:, j], F[:, j + 1]
            X, Z = (C, P) if classic else (P, C)
            mask = frames >= j + 1
            if par == "a":
                col = _screw_on_points(X[:, :3, 0], X[:, :3, 3], False, pts, mask)
            elif par == "alpha":
                col = _screw_on_points(X[:, :3, 0], X[:, :3, 3], True, pts, mask)
            elif par == "d":
                col = _screw_on_points(Z[:, :3, 2], Z[:, :3, 3], False, pts, mask)
            else:
                col = _screw_on_points(Z[:, :3, 2], Z[:, :3, 3], True, pts, mask)
        else:
            B = F[:, 0]
            mask = frames >= 0
            ones = np.ones(K)
            zeros = np.zeros(K)
            if par in ("x", "y", "z"):
                ax = np.zeros((K, 3))
                ax[:, "xyz".index(par)] = 1.0
                col = _screw_on_points(ax, B[:, :3, 3], False, pts, mask)
            elif par == "roll":
                col = _screw_on_points(B[:, :3, 0], B[:, :3, 3], True, pts, mask)
            elif par == "pitch":
                yaw = np.arctan2(B[:, 1, 0], B[:, 0, 0])
                ax = np.stack([-np.sin(yaw), np.cos(yaw), zeros], axis=1)
                col = _screw_on_points(ax, B[:, :3, 3], True, pts, mask)
            else:
                ax = np.stack([zeros, zeros, ones], axis=1)
                col = _screw_on_points(ax, B[:, :3, 3], True, pts, mask)
        Jd[:, :, :, c] = col
    return Jd, Jq[:, :, :, problem.free_joints]


def link_points(
    problem: SynthesisProblem, z: Array, samples: int = 4
) -> tuple[Array, Array, Array, NDArray[np.int64]]:
    """Skeleton points of every task configuration and their Jacobians.

    Returns ``points (K, L, 3)``, ``J_design (K, L, 3, p)``, ``J_joints (K, L, 3, n_f)``
    and ``owner (K, L)`` (the task point each belongs to), with
    ``L = 1 + (N + 1) · samples``.
    """
    O, Jd, Jq = origin_jacobians(problem, z)
    n_frames = O.shape[1]
    s = np.arange(1, samples + 1) / samples
    k0 = np.repeat(np.arange(n_frames - 1), samples)
    ss = np.tile(s, n_frames - 1)
    a = (1.0 - ss)[None, :, None]
    b = ss[None, :, None]
    pts = np.concatenate([O[:, :1], a * O[:, k0] + b * O[:, k0 + 1]], axis=1)
    a4, b4 = a[..., None], b[..., None]
    Jd_s = np.concatenate([Jd[:, :1], a4 * Jd[:, k0] + b4 * Jd[:, k0 + 1]], axis=1)
    Jq_s = np.concatenate([Jq[:, :1], a4 * Jq[:, k0] + b4 * Jq[:, k0 + 1]], axis=1)
    owner = np.broadcast_to(np.arange(problem.K)[:, None], pts.shape[:2]).astype(np.int64)
    return pts, Jd_s, Jq_s, owner
