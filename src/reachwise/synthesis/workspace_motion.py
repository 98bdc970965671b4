"""Workspace avoidance of the ``dls`` solver (P-II Eq. 29–33, P-I Eq. 27–31).

Link points closer than a margin to the workspace boundary (e.g. the tunnel envelope)
are pushed back by the Khatib-style velocity ``k (margin − distance)`` along the
boundary normal, mapped through the transposed point Jacobians; the solver projects
this motion into the null space of the task (``solvers``).

Pure maths: numpy in and out.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from reachwise.synthesis.problem import SynthesisProblem
from reachwise.synthesis.solver_options import SolverOptions, Workspace
from reachwise.synthesis.workspace_points import link_points

Array = NDArray[np.float64]


def workspace_clear(
    problem: SynthesisProblem, z: Array, ws: Workspace | None, opt: SolverOptions
) -> bool:
    """Whether every sampled link point lies inside the workspace (``d >= 0``)."""
    if ws is None:
        return True
    pts, _, _, _ = link_points(problem, z, opt.samples_per_link)
    return bool(np.all(ws.signed_distance(pts.reshape(-1, 3)) >= 0.0))


def workspace_motion(
    problem: SynthesisProblem, z: Array, ws: Workspace, opt: SolverOptions
) -> tuple[Array | None, Array | None]:
    """``Σ J_dᵀ k (margin − distance) n`` over violating link points (P-II Eq. 29–31)."""
    pts, Jd, Jq, owner = link_points(problem, z, opt.samples_per_link)
    flat = pts.reshape(-1, 3)
    sd = ws.signed_distance(flat)
    bad = np.flatnonzero(sd < opt.workspace_margin)
    if bad.size == 0:
        return None, None
    g = ws.gradient(flat[bad])
    v = opt.workspace_gain * (opt.workspace_margin - sd[bad])[:, None] * g  # (k, 3)
    Jd_bad = Jd.reshape(-1, 3, problem.p)[bad]
    Jq_bad = Jq.reshape(-1, 3, problem.n_free_joints)[bad]
    nd = np.einsum("kia,ki->a", Jd_bad, v)
    nq = np.zeros((problem.K, problem.n_free_joints))
    np.add.at(nq, owner.reshape(-1)[bad], np.einsum("kia,ki->ka", Jq_bad, v))
    return nd, nq
