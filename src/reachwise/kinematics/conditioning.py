"""The local conditioning index and its exact gradient (P-I Eq. 34–37, P-II Eq. 38–39).

``LCI = σ_min / σ_max`` of the length-scaled Jacobian ``J̃ = S J``, ``S = diag(I, L I)``
with the nominal length ``L = ‖p − b‖`` from the base origin ``b`` to the tool point
(``indices``). For a change of any parameter ``θ`` (a joint value, a DH parameter or a
base coordinate) with a simple singular value ``σ_i`` and singular vectors ``u_i``,
``v_i``, ``∂σ_i/∂θ = u_iᵀ (∂J̃/∂θ) v_i`` (first-order perturbation of the SVD), and

    ∂J̃/∂θ = S ∂J/∂θ + (∂L/∂θ) [0; J_ω],    ∂L/∂θ = (p − b)ᵀ (v_θ − ḃ_θ) / L,

where ``∂J/∂θ`` comes from ``jacobian_derivative``, ``v_θ`` is the tool-point velocity of
the parameter (its twist) and ``ḃ_θ`` the base origin's (a unit vector for base x, y, z,
0 otherwise). Then ``∂LCI/∂θ = (σ_max ∂σ_min − σ_min ∂σ_max) / σ_max²``. Where the
smallest or largest singular value is repeated the LCI is not differentiable; the
formula then gives one element of its generalized gradient.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.kinematics.indices import scaled_jacobian
from reachwise.kinematics.jacobian_derivative import jacobian_derivatives

if TYPE_CHECKING:
    from reachwise.kinematics.robot import Robot

Array = NDArray[np.float64]


def lci_from_jacobians(J: Array, dJ: Array, length: Array, dlength: Array) -> tuple[Array, Array]:
    """LCI ``(m,)`` and its derivatives ``(m, S)`` from Jacobians ``J (m, 6, n)``, their
    derivatives ``dJ (m, 6, n, S)``, nominal lengths ``(m,)`` and their derivatives
    ``(m, S)`` (module docstring)."""
    Js = scaled_jacobian(J, length)
    dJs = np.array(dJ, dtype=np.float64)
    dJs[:, 3:] *= length[:, None, None, None]
    dJs[:, 3:] += J[:, 3:, :, None] * dlength[:, None, None, :]
    U, s, Vt = np.linalg.svd(Js, full_matrices=False)
    r = s.shape[1] - 1
    d_max = np.einsum("mi,mijs,mj->ms", U[:, :, 0], dJs, Vt[:, 0, :])
    d_min = np.einsum("mi,mijs,mj->ms", U[:, :, r], dJs, Vt[:, r, :])
    smax, smin = s[:, 0], s[:, r]
    ok = smax > 0
    safe = np.where(ok, smax, 1.0)
    value = np.where(ok, smin / safe, 0.0)
    grad = np.where(ok[:, None], (d_min * safe[:, None] - smin[:, None] * d_max), 0.0)
    return value, grad / (safe * safe)[:, None]


def lci_gradient(
    robot: Robot, q: ArrayLike, params: Sequence[tuple[str, int, str]] = ()
) -> tuple[Array, Array]:
    """LCI at each configuration of ``q (m, n)`` and its gradient ``(m, n + s)`` with
    respect to the joint values and then ``params`` (``DesignSpace.free`` entries)."""
    T, J, W, dJ = jacobian_derivatives(robot, q, params)
    b = robot.base[:3, 3]
    r = T[:, :3, 3] - b
    length = np.linalg.norm(r, axis=1)
    db = np.zeros((W.shape[2], 3))
    for k, (kind, _, p) in enumerate(params):
        if kind == "base" and p in ("x", "y", "z"):
            db[robot.n + k, "xyz".index(p)] = 1.0
    vel = np.moveaxis(W[:, :3, :], 1, 2) - db[None]  # (m, S, 3)
    safe = np.where(length > 0, length, 1.0)
    dlength = np.einsum("mi,msi->ms", r, vel) / safe[:, None]
    return lci_from_jacobians(J, dJ, length, dlength)
