"""Exact clearance of the design bodies at every task pose, with analytic gradients.

A template's bodies (``reachwise.kinematics.design_bodies.DesignBody``) are cut
into convex *parts* (``clearance_parts``): segments (a capsule's axis, with its
radius) and boxes. The *terms* of the clearance, per task pose, are:

* **body vs environment** — the tunnel envelope's free space is convex
  (``reachwise.tasks.workspace.TunnelEnvelope``), so its signed distance ``s`` is
  concave and its minimum over a segment or a box is reached at an end point or a
  corner: a capsule part gives the two terms ``s(A) − r`` and ``s(B) − r``, a box its
  eight corners ``s(c)`` — exact, and each term smooth where ``s`` is. A capsule's
  contact zone shortens its environment segment by the zone's length;
* **body vs body** (watched pairs, ``watched_pairs``) — two segments: Ericson's closest
  points ``p_a, p_b`` give ``|p_a − p_b| − r_a − r_b``; a segment and a box: the box's
  signed distance ``φ`` (negative inside) is convex, so ``min_t φ(A + t (B − A))`` is
  found by golden-section search on ``t ∈ [0, 1]`` (to 1e-13) and minus ``r`` is the
  exact distance. When they overlap it is a penetration depth (the deepest point of the
  axis in the box), whose gradient below is then a subgradient only.

The gradient of each term w.r.t. the decision vector (design variables, base, every
pose's free joints) follows the envelope theorem: with the closest points fixed, a term
moves with the unit normal ``n`` at them, ``∇d = nᵀ (J(p_a) − J(p_b))``, where ``J(p)`` is
the Jacobian of the material point ``p`` (P-I Eq. 15–19 screws,
``workspace_points.attached_point_jacobians``), interpolated along a segment from its
end points. An end point of a design-following capsule (the *elbow* between the ``a``
and ``d`` segments) moves with its own DH parameter as well, which is added explicitly.

Pure maths: numpy in and out.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError
from reachwise.geometry.mesh_distance import segment_closest_parameters
from reachwise.kinematics.design_bodies import DesignBody
from reachwise.kinematics.fk import fk_all
from reachwise.kinematics.robot import Robot
from reachwise.synthesis.clearance_parts import (
    ENVIRONMENT,
    Anchor,
    ClearanceTerms,
    Part,
    as_vec3,
    body_frame,
    segments_of,
    watched_pairs,
)
from reachwise.synthesis.workspace_points import attached_point_jacobians

if TYPE_CHECKING:
    from reachwise.synthesis.problem import SynthesisProblem
    from reachwise.tasks.workspace import TunnelEnvelope

__all__ = [
    "ENVIRONMENT",
    "Anchor",
    "ClearanceModel",
    "ClearanceTerms",
    "Part",
    "Unservable",
    "body_frame",
    "box_signed_distance",
    "task_fixed_frames",
    "unservable_poses",
    "watched_pairs",
]

Array = NDArray[np.float64]
_GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0
_GOLDEN_ITER = 64


class ClearanceModel:
    """The parts, anchors and terms of a template's bodies (module docstring).

    ``envelope`` adds the body-vs-environment terms; ``clearance`` (m) is what every
    term must keep.
    """

    def __init__(
        self, robot: Robot, envelope: TunnelEnvelope | None = None, clearance: float = 0.0
    ) -> None:
        if not robot.design.bodies:
            raise InputError(robot.name, "design.bodies", "no bodies to keep clear")
        self.robot = robot
        self.envelope = envelope
        self.clearance = float(clearance)
        self.anchors: list[Anchor] = []
        self.parts: list[Part] = []
        for i, b in enumerate(robot.design.bodies):
            self._add_body(i, b)
        self.pairs = watched_pairs(robot)

    def _anchor(self, a: Anchor) -> int:
        if a not in self.anchors:
            self.anchors.append(a)
        return self.anchors.index(a)

    def _add_body(self, i: int, b: DesignBody) -> None:
        f = body_frame(self.robot, b)
        if b.follows_design:
            for a0, a1 in segments_of(self.robot, b):
                ends = (self._anchor(a0), self._anchor(a1))
                self.parts.append(Part(i, "segment", ends, b.radius, ends))
        elif b.shape == "capsule":
            s, e = np.array(b.start), np.array(b.end)
            ends = (self._anchor(Anchor(f, b.start)), self._anchor(Anchor(f, b.end)))
            env = ends
            if b.contact > 0:
                cut = e - b.contact * (e - s) / np.linalg.norm(e - s)
                env = (ends[0], self._anchor(Anchor(f, as_vec3(cut))))
            self.parts.append(Part(i, "segment", ends, b.radius, env))
        else:
            T = np.array(b.origin)
            h = np.array(b.size) / 2
            signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
            corners = (T[:3, :3] @ (signs * h).T).T + T[:3, 3]
            corner_ids = tuple(self._anchor(Anchor(f, as_vec3(c))) for c in corners)
            part = Part(i, "box", corner_ids, 0.0, corner_ids, f, as_vec3(h), b.origin)
            self.parts.append(part)

    @cached_property
    def labels(self) -> tuple[tuple[str, str], ...]:
        """The pair of every term, in term order."""
        names = [b.name for b in self.robot.design.bodies]
        out: list[tuple[str, str]] = []
        if self.envelope is not None:
            for part in self.parts:
                out += [(names[part.body], ENVIRONMENT)] * len(part.env_ends)
        for pa, pb in self._part_pairs:
            out.append((names[self.parts[pa].body], names[self.parts[pb].body]))
        return tuple(out)

    @cached_property
    def _part_pairs(self) -> list[tuple[int, int]]:
        watched = set(self.pairs)
        out = []
        for ia, a in enumerate(self.parts):
            for ib, b in enumerate(self.parts):
                if (a.body, b.body) in watched:
                    # a box part goes second
                    out.append((ib, ia) if a.kind == "box" else (ia, ib))
        return out

    # ---- evaluation -----------------------------------------------------------------
    @cached_property
    def _anchor_table(self) -> tuple[NDArray[np.int64], Array, list[tuple[int, int]]]:
        """Every anchor's frame ``(A,)`` and local point ``(A, 3)``, and the
        ``(anchor, DH row)`` of the elbows, whose local point follows the design."""
        frames = np.array([a.frame for a in self.anchors], dtype=np.int64)
        local = np.array([a.local for a in self.anchors], dtype=float).reshape(-1, 3)
        elbows = [(i, a.elbow) for i, a in enumerate(self.anchors) if a.elbow >= 0]
        return frames, local, elbows

    def anchor_points(self, problem: SynthesisProblem, z: Array) -> tuple[Array, Array, Array]:
        """World anchor points ``(K, A, 3)``, frames ``(K, N+2, 4, 4)`` and the robot's
        DH table at the design of ``z`` (with each pose's joint values)."""
        design, Q = problem.split(z)
        robot = problem.robot_at(design)
        F = np.asarray(fk_all(robot, Q))
        frames, local0, elbows = self._anchor_table
        local = np.broadcast_to(local0, (problem.K, *local0.shape)).copy()
        for i, row in elbows:
            local[:, i] = self._elbow_local(robot, Q, row)
        W = F[:, frames]
        pts = np.einsum("kaij,kaj->kai", W[:, :, :3, :3], local) + W[:, :, :3, 3]
        return pts, F, Q

    def _elbow_local(self, robot: Robot, Q: Array, row: int) -> Array:
        """The elbow of DH row ``row`` in frame ``row`` (module docstring): ``(a, 0, 0)``
        for modified DH, ``(0, 0, d + q)`` for classic."""
        K = Q.shape[0]
        out = np.zeros((K, 3))
        if robot.convention == "classic":
            d = np.full(K, robot.dh[row, 2])
            if robot.joints[row].type == "prismatic":
                d = d + Q[:, robot.movable_joints.index(row)]
            out[:, 2] = d
        else:
            out[:, 0] = robot.dh[row, 0]
        return out

    def _anchor_jacobians(
        self, problem: SynthesisProblem, F: Array, pts: Array
    ) -> tuple[Array, Array]:
        frames = np.array([a.frame for a in self.anchors], dtype=np.int64)
        Jd, Jq = attached_point_jacobians(problem, F, frames, pts)
        classic = self.robot.convention == "classic"
        cols = {
            (r, p): c for c, (kind, r, p) in enumerate(self.robot.design.free) if kind == "joint"
        }
        qcols = {int(k): i for i, k in enumerate(problem.free_joints)}
        for i, a in enumerate(self.anchors):
            if a.elbow < 0:
                continue
            j = a.elbow
            par = "d" if classic else "a"
            axis = F[:, j, :3, 2] if classic else F[:, j, :3, 0]
            if (j, par) in cols:
                Jd[:, i, :, cols[(j, par)]] += axis
            if classic and self.robot.joints[j].type == "prismatic":
                qi = self.robot.movable_joints.index(j)
                if qi in qcols:
                    Jq[:, i, :, qcols[qi]] += axis
        return Jd, Jq

    def terms(self, problem: SynthesisProblem, z: Array) -> ClearanceTerms:
        """Every term's clearance and gradient at ``z`` (module docstring)."""
        pts, F, _ = self.anchor_points(problem, z)
        Jd, Jq = self._anchor_jacobians(problem, F, pts)
        D, GD, GQ = self._evaluate(problem, pts, F, (Jd, Jq))
        assert GD is not None and GQ is not None
        return ClearanceTerms(D, GD, GQ, self.labels)

    def distances(self, problem: SynthesisProblem, z: Array) -> Array:
        """Every term's clearance ``(K, m)`` at ``z`` without the gradients: what a trial
        step of the solver needs (the same values as ``terms``)."""
        pts, F, _ = self.anchor_points(problem, z)
        return self._evaluate(problem, pts, F, None)[0]

    @cached_property
    def _env_terms(self) -> tuple[NDArray[np.int64], Array]:
        """The anchors of the environment terms and their parts' radii, in term order."""
        idx = [e for part in self.parts for e in part.env_ends]
        rad = [part.radius for part in self.parts for _ in part.env_ends]
        return np.array(idx, dtype=np.int64), np.array(rad, dtype=float)

    @cached_property
    def _pair_kinds(self) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
        """The part pairs of two segments and those of a segment and a box."""
        seg = [(a, b) for a, b in self._part_pairs if self.parts[b].kind == "segment"]
        box = [(a, b) for a, b in self._part_pairs if self.parts[b].kind == "box"]
        return seg, box

    @cached_property
    def _segment_table(self) -> tuple[NDArray[np.int64], Array]:
        """The end anchors ``(4, m)`` (``a0, a1, b0, b1``) of the segment pairs and the
        sums of their radii ``(m,)``."""
        pairs = self._pair_kinds[0]
        ends = [
            [self.parts[a].ends[0] for a, _ in pairs],
            [self.parts[a].ends[1] for a, _ in pairs],
            [self.parts[b].ends[0] for _, b in pairs],
            [self.parts[b].ends[1] for _, b in pairs],
        ]
        rad = [self.parts[a].radius + self.parts[b].radius for a, b in pairs]
        return np.array(ends, dtype=np.int64).reshape(4, -1), np.array(rad, dtype=float)

    def _evaluate(
        self, problem: SynthesisProblem, pts: Array, F: Array, jac: tuple[Array, Array] | None
    ) -> tuple[Array, Array | None, Array | None]:
        """Distances in label order and, given the anchor Jacobians ``jac``, their
        gradients w.r.t. the design and the free joints."""
        K = pts.shape[0]
        dist: list[Array] = []
        gd: list[Array] = []
        gq: list[Array] = []
        if self.envelope is not None:
            idx, rad = self._env_terms
            P = pts[:, idx].reshape(-1, 3)
            m = len(idx)
            if jac is None:
                dist.append(self.envelope.signed_distance(P).reshape(K, m) - rad)
            else:
                s, g = self.envelope.signed_distance_and_gradient(P)
                g = g.reshape(K, m, 3)
                dist.append(s.reshape(K, m) - rad)
                gd.append(np.einsum("kmi,kmia->kma", g, jac[0][:, idx]))
                gq.append(np.einsum("kmi,kmia->kma", g, jac[1][:, idx]))
        seg, box = self._pair_kinds
        pair_terms = [self._segment_pairs(pts, jac)] if seg else []
        if box:
            pair_terms.append(self._box_pairs(problem, box, pts, F, jac))
        for d, a, b in pair_terms:
            dist.append(d)
            if a is not None and b is not None:
                gd.append(a)
                gq.append(b)
        # terms in label order: environment, then the part pairs in _part_pairs order
        order = self._pair_order
        D = np.concatenate(dist, axis=1) if dist else np.zeros((K, 0))
        if jac is None:
            return D[:, order], None, None
        GD = np.concatenate(gd, axis=1) if gd else np.zeros((K, 0, problem.p))
        GQ = np.concatenate(gq, axis=1) if gq else np.zeros((K, 0, problem.n_free_joints))
        return D[:, order], GD[:, order], GQ[:, order]

    @cached_property
    def _pair_order(self) -> NDArray[np.int64]:
        """Where each computed term (environment, segment pairs, box pairs) goes in
        label order."""
        seg, box = self._pair_kinds
        n_env = len(self.labels) - len(self._part_pairs)
        computed = list(range(n_env)) + [n_env + self._part_pairs.index(p) for p in seg + box]
        order = np.empty(len(computed), dtype=np.int64)
        order[np.array(computed, dtype=np.int64)] = np.arange(len(computed))
        return order

    def _segment_pairs(
        self, pts: Array, jac: tuple[Array, Array] | None
    ) -> tuple[Array, Array | None, Array | None]:
        """The segment pairs' distances ``(K, m)`` and, given ``jac``, gradients (the
        pairs are ``_pair_kinds``' first list, whose ends ``_segment_table`` holds)."""
        K = pts.shape[0]
        ends, rad = self._segment_table
        m = ends.shape[1]
        A0, A1, B0, B1 = (pts[:, i].reshape(-1, 3) for i in ends)
        s, t = segment_closest_parameters(A0, A1, B0, B1)
        diff = (A0 + s[:, None] * (A1 - A0)) - (B0 + t[:, None] * (B1 - B0))
        nrm = np.sqrt(np.einsum("ij,ij->i", diff, diff))
        if jac is None:
            return nrm.reshape(K, m) - rad, None, None
        n = np.where(nrm[:, None] > 1e-15, diff / np.where(nrm > 1e-15, nrm, 1.0)[:, None], 0.0)
        s, t, n = s.reshape(K, m, 1), t.reshape(K, m, 1), n.reshape(K, m, 3)
        n4 = np.concatenate([n, n, n, n], axis=1)  # the normal at each of the four ends
        flat = ends.ravel()

        def grad(J: Array) -> Array:
            # nᵀ J interpolated along both segments: contract the normal first, at the
            # four ends of every pair in one product
            nJ = np.einsum("kmi,kmia->kma", n4, J[:, flat]).reshape(K, 4, m, -1)
            nJ0, nJ1, nK0, nK1 = nJ[:, 0], nJ[:, 1], nJ[:, 2], nJ[:, 3]
            return np.asarray((1 - s) * nJ0 + s * nJ1 - (1 - t) * nK0 - t * nK1)

        return nrm.reshape(K, m) - rad, grad(jac[0]), grad(jac[1])

    def _box_pairs(
        self,
        problem: SynthesisProblem,
        pairs: list[tuple[int, int]],
        pts: Array,
        F: Array,
        jac: tuple[Array, Array] | None,
    ) -> tuple[Array, Array | None, Array | None]:
        K, m = pts.shape[0], len(pairs)
        a0 = [self.parts[a].ends[0] for a, _ in pairs]
        a1 = [self.parts[a].ends[1] for a, _ in pairs]
        rad = np.array([self.parts[a].radius for a, _ in pairs])
        frames = np.array([self.parts[b].frame for _, b in pairs], dtype=np.int64)
        O = np.stack([np.array(self.parts[b].origin) for _, b in pairs])  # (m, 4, 4)
        W = np.einsum("kmij,mjl->kmil", F[:, frames], O)  # box poses in world
        half = np.array([self.parts[b].half for _, b in pairs])
        A, B = pts[:, a0], pts[:, a1]
        R, c = W[:, :, :3, :3], W[:, :, :3, 3]
        la = np.einsum("kmji,kmj->kmi", R, A - c)
        lb = np.einsum("kmji,kmj->kmi", R, B - c)

        def along(tt: Array) -> Array:
            return box_signed_distance(la + tt[..., None] * (lb - la), half)[0]

        t = _golden_min(along, (K, m))
        phi, g_local = box_signed_distance(la + t[..., None] * (lb - la), half)
        if jac is None:
            return phi - rad, None, None
        X = A + t[..., None] * (B - A)
        g = np.einsum("kmij,kmj->kmi", R, g_local)
        Jx_d, Jx_q = attached_point_jacobians(problem, F, frames, X)
        tt = t[..., None, None]

        def grad(J: Array, Jx: Array) -> Array:
            Ja = (1 - tt) * J[:, a0] + tt * J[:, a1]
            return np.einsum("kmi,kmia->kma", g, Ja - Jx)

        return phi - rad, grad(jac[0], Jx_d), grad(jac[1], Jx_q)


def box_signed_distance(x: Array, half: Array) -> tuple[Array, Array]:
    """Signed distance (negative inside) of local points ``x (..., m, 3)`` to boxes of
    half sizes ``half (m, 3)`` centred at the origin, and its gradient ``(..., m, 3)``."""
    sgn = np.where(x < 0, -1.0, 1.0)
    q = np.abs(x) - half
    qp = np.maximum(q, 0.0)
    out = np.linalg.norm(qp, axis=-1)
    qmax = q.max(axis=-1)
    phi = out + np.minimum(qmax, 0.0)
    k = np.argmax(q, axis=-1)
    g_in = np.zeros_like(x)
    np.put_along_axis(g_in, k[..., None], np.take_along_axis(sgn, k[..., None], -1), -1)
    safe = np.where(out > 0, out, 1.0)[..., None]
    g = np.where((out > 0)[..., None], sgn * qp / safe, g_in)
    return phi, g


def _golden_min(f: Callable[[Array], Array], shape: tuple[int, ...]) -> Array:
    """Minimizer in ``[0, 1]`` of a convex ``f`` (elementwise over ``shape`` problems:
    ``f`` maps an array of ``t`` of that shape to values) by golden-section search,
    bracket below 1e-13 after 64 steps."""
    lo, hi = np.zeros(shape), np.ones(shape)
    x1 = hi - _GOLDEN * (hi - lo)
    x2 = lo + _GOLDEN * (hi - lo)
    f1, f2 = f(x1), f(x2)
    for _ in range(_GOLDEN_ITER):
        left = f1 <= f2  # the minimum lies in [lo, x2]
        hi = np.where(left, x2, hi)
        lo = np.where(left, lo, x1)
        nx1 = np.where(left, hi - _GOLDEN * (hi - lo), x2)
        nx2 = np.where(left, x1, lo + _GOLDEN * (hi - lo))
        x1, x2 = nx1, nx2
        fn = f(np.where(left, x1, x2))
        f1, f2 = np.where(left, fn, f2), np.where(left, f1, fn)
    t = (lo + hi) / 2
    # the ends, where a monotone f has its minimum exactly
    ends = np.stack([np.zeros(shape), t, np.ones(shape)])
    vals = np.stack([f(e) for e in ends])
    return np.asarray(np.take_along_axis(ends, np.argmin(vals, axis=0)[None], 0)[0])


@dataclass(frozen=True)
class Unservable:
    """A task pose that no design can serve: its ``index`` and ``name`` in the task and
    the ``reason`` (which body the pose itself places too close to what)."""

    index: int
    name: str
    reason: str


def task_fixed_frames(robot: Robot) -> list[int]:
    """Rows of ``fk_all`` whose pose relative to the tool no joint value and no design
    parameter changes (every DH row from the frame to the tool is a fixed joint without
    a free parameter): a 6-D task pose places them completely."""
    N = len(robot.joints)
    designed = {j for kind, j, _ in robot.design.free if kind == "joint"}
    out = [N + 1]
    for f in range(N, -1, -1):
        if robot.joints[f].movable if f < N else False:
            break
        if f < N and f in designed:
            break
        out.append(f)
    return sorted(out)


def unservable_poses(
    model: ClearanceModel, task_poses: Array, dims: NDArray[np.int64], names: tuple[str, ...]
) -> list[Unservable]:
    """Poses at which a body fixed to the tool (``task_fixed_frames``) keeps less than the
    clearance from the environment whatever the design: 6-D poses place such a body
    exactly; 5-D poses leave the roll about the tool axis free, checked on 720 rolls
    with the Lipschitz bound of the roll added (a pose is reported only when no roll
    can serve it). 3-D poses fix no orientation and are never reported."""
    env = model.envelope
    if env is None:
        return []
    robot = model.robot
    fixed = set(task_fixed_frames(robot))
    F0 = np.asarray(fk_all(robot, np.zeros(robot.n)))
    tool_in = {f: np.linalg.inv(F0[f]) @ F0[-1] for f in fixed}
    names_b = [b.name for b in robot.design.bodies]
    items: list[tuple[int, Array, float]] = []  # (body, point in tool frame, radius)
    for part in model.parts:
        for e in part.env_ends:
            a = model.anchors[e]
            if a.frame not in fixed or a.elbow >= 0:
                continue
            local = np.array([*a.local, 1.0])
            in_tool = np.linalg.solve(tool_in[a.frame], local)[:3]
            items.append((part.body, in_tool, part.radius))
    if not items:
        return []
    P = np.stack([p for _, p, _ in items])  # (n, 3) in the tool frame
    rad = np.array([r for _, _, r in items])
    n_roll = 720
    rho = float(np.hypot(P[:, 0], P[:, 1]).max())
    slack = rho * np.pi / n_roll  # largest change between neighbouring rolls
    out = []
    for k in np.flatnonzero(dims >= 5):
        rolls = np.array([0.0]) if dims[k] == 6 else 2 * np.pi * np.arange(n_roll) / n_roll
        c, s = np.cos(rolls), np.sin(rolls)
        Rz = np.zeros((rolls.size, 3, 3))
        Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1], Rz[:, 2, 2] = c, -s, s, c, 1.0
        T = task_poses[k]
        W = np.einsum("ij,rjl,nl->rni", T[:3, :3], Rz, P) + T[:3, 3]
        d = env.signed_distance(W.reshape(-1, 3)).reshape(rolls.size, -1) - rad
        worst = d.min(axis=1)
        best = int(np.argmax(worst))
        bound = float(worst[best]) + (slack if dims[k] == 5 else 0.0)
        if bound < model.clearance:
            body = names_b[items[int(np.argmin(d[best]))][0]]
            how = "at this pose" if dims[k] == 6 else "at any roll about the tool axis"
            out.append(
                Unservable(
                    int(k),
                    names[k],
                    f"{body} keeps at most {float(worst[best]):.3f} m from the tunnel {how}"
                    f" (< clearance {model.clearance:g} m); the pose alone places it",
                )
            )
    return out
