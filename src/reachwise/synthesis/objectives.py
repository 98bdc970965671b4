"""Design objectives after reach: named terms, their exact gradients and their weights.

Once every task pose is reached, a synthesis can improve the design within the set of
reaching designs (``improve``). Each objective is a function of the decision vector
``z = [design | q_1 … q_K]`` (``problem``) with an analytic gradient:

* ``gci`` — maximize the global conditioning index, the mean LCI of the length-scaled
  Jacobian over the task postures (P-II Eq. 38; P-I Eq. 34–37). Gradient: SVD
  perturbation with the DH-parameter Jacobian's derivative (``kinematics.conditioning``).
* ``kci`` — maximize the worst LCI over the task (P-II Eq. 39; ``1 / max κ``). The
  minimum is not differentiable where two postures tie, so the optimized term is the
  soft minimum ``−τ log((1/K) Σ exp(−LCI_k / τ))`` (``τ = kci_temperature``, between the
  minimum and the mean and within ``τ log K`` of the minimum); the true KCI is reported.
* ``size`` — minimize ``Σ |a| + Σ |d|`` over the free length parameters (m): a proxy of
  the structure's mass and cost (P-I §5: "the optimized manipulator can be smaller").
* ``limits`` — keep joint values away from their limits: the mean over postures and free
  joints of ``((q − q_mid) / (q_range / 2))²`` (0 at mid-range, 1 at a limit).
* ``bounds`` — keep each design parameter a fraction ``margin`` of its range inside its
  bounds: ``Σ (max(0, m − u)² + max(0, u − 1 + m)²) / m²`` with ``u`` the parameter
  normalized to ``[0, 1]`` (P-I Table 3's scale); 0 inside the band, 1 at a bound.
* ``clearance`` — maximize the smallest clearance (m) of the design bodies over the task:
  every term ``d_i`` of every pose (``clearance.ClearanceModel``: watched pairs and
  bodies against the tunnel). The minimum over the terms is not differentiable where
  two tie, so the optimized term is the log-sum-exp soft minimum
  ``−τ log Σ_i exp(−d_i / τ)`` (``τ = clearance_temperature``, 5 mm), whose gradient is
  the softmax-weighted mean of the terms' gradients. It lies between ``min d − τ log N``
  (``N`` terms) and ``min d``: never above the true smallest clearance, so a positive
  value proves a clear design; in practice only the few terms within a few ``τ`` of the
  minimum count, which puts it within millimetres of it. A p-norm of ``1 / d`` (the other
  usual smooth minimum) is not used: a clearance may be negative (an overlap). The true
  smallest clearance is what results report. It needs the template's bodies
  (``design.bodies``) and their model. Terms that no design changes are left out
  (``designable_terms``): a body fixed to the tool (the feed) against the tunnel at a
  6-D pose, which the pose alone places. They stay constraints of the solve; in the
  objective they would cap the minimum at a value no design can raise (on tunnel-87
  the feed at the collar points nearest the wall) and flatten it.

The weighted objective to minimize is ``Σ_i w_i s_i f_i / f_i⁰`` with ``s_i = −1`` for a
term to maximize and ``f_i⁰`` the term's magnitude at a reference design (the reach-only
design the improvement starts from): a weight trades *relative* changes, so
``gci:1,size:0.2`` values a 1 % higher GCI like a 5 % smaller structure, whatever the
units. Pure math.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError, UnknownName
from reachwise.kinematics.conditioning import lci_gradient
from reachwise.kinematics.robot import OBJECTIVES
from reachwise.synthesis.clearance import ClearanceModel, task_fixed_frames
from reachwise.synthesis.problem import SynthesisProblem

Array = NDArray[np.float64]

LENGTH_PARAMS = ("a", "d")
#: The soft minimum's temperature of the ``clearance`` objective (m).
CLEARANCE_TEMPERATURE = 0.005


def check_objective(
    weights: Mapping[str, float] | None, source: str = "objective"
) -> dict[str, float]:
    """Validated weights ``{name: weight}`` (names from ``OBJECTIVES``, weights finite
    and ``>= 0``, at least one positive); ``None`` or an empty mapping gives ``{}``."""
    if not weights:
        return {}
    out: dict[str, float] = {}
    for name, w in weights.items():
        if name not in OBJECTIVES:
            raise UnknownName(source, "objective", str(name), OBJECTIVES)
        try:
            v = float(w)
        except (TypeError, ValueError):
            raise InputError(source, f"objective.{name}", f"weight {w!r} is not a number") from None
        if not math.isfinite(v) or v < 0:
            raise InputError(
                source, f"objective.{name}", f"weight must be finite and >= 0, got {v}"
            )
        out[str(name)] = v
    if not any(v > 0 for v in out.values()):
        raise InputError(source, "objective", "at least one weight must be positive")
    return out


def parse_objective(text: str, source: str = "--objective") -> dict[str, float]:
    """``"gci:1,size:0.2"`` → ``{"gci": 1.0, "size": 0.2}``; a name without weight has 1."""
    out: dict[str, float] = {}
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        name, _, w = part.partition(":")
        try:
            out[name.strip()] = float(w) if w.strip() else 1.0
        except ValueError:
            raise InputError(source, name.strip(), f"weight {w!r} is not a number") from None
    if not out:
        raise InputError(source, "objective", "empty; e.g. gci:1,size:0.2")
    return check_objective(out, source)


@dataclass(frozen=True)
class Terms:
    """Raw values of the objective terms at one ``z`` and their gradients ``(size,)``.

    ``lci`` holds the LCI of every task posture (when ``gci`` or ``kci`` was asked)."""

    values: dict[str, float]
    gradients: dict[str, Array]
    lci: Array = field(default_factory=lambda: np.zeros(0))


def size_columns(problem: SynthesisProblem) -> NDArray[np.int64]:
    """Indices (into the design vector) of the free ``a`` and ``d`` parameters."""
    free = problem.template.design.free
    return np.array([i for i, (k, _, p) in enumerate(free) if k == "joint" and p in LENGTH_PARAMS],
                    dtype=np.int64)  # fmt: skip


def evaluate_terms(
    problem: SynthesisProblem,
    z: Array,
    names: tuple[str, ...] | list[str],
    margin: float = 0.05,
    kci_temperature: float = 0.002,
    abs_smoothing: float = 1e-4,
    bodies: ClearanceModel | None = None,
    clearance_temperature: float = CLEARANCE_TEMPERATURE,
) -> Terms:
    """Values and exact gradients of the named terms at ``z`` (module docstring);
    ``clearance`` needs the bodies' model ``bodies``."""
    p, K, nf = problem.p, problem.K, problem.n_free_joints
    values: dict[str, float] = {}
    grads: dict[str, Array] = {}
    design, Q = problem.split(z)
    lcis = np.zeros(0)
    if "gci" in names or "kci" in names:
        robot = problem.robot_at(design)
        lcis, dl = lci_gradient(robot, Q, problem.template.design.free)
        n = robot.n
        fj = problem.free_joints

        def to_z(weights: Array) -> Array:
            g = np.empty(problem.size)
            g[:p] = weights @ dl[:, n:]
            g[p:] = (weights[:, None] * dl[:, fj]).ravel()
            return g

        if "gci" in names:
            values["gci"] = float(lcis.mean())
            grads["gci"] = to_z(np.full(K, 1.0 / K))
        if "kci" in names:
            t = kci_temperature
            x = -lcis / t
            mx = float(x.max())
            ex = np.exp(x - mx)
            values["kci"] = float(-t * (mx + math.log(ex.sum() / K)))
            grads["kci"] = to_z(ex / ex.sum())
    if "size" in names:
        cols = size_columns(problem)
        x = design[cols]
        d = abs_smoothing
        r = np.sqrt(x * x + d * d)
        values["size"] = float(np.sum(r - d))
        g = np.zeros(problem.size)
        g[cols] = x / r
        grads["size"] = g
    if "limits" in names:
        lo, hi = problem.bounds
        zq = z[p:].reshape(K, nf)
        mid = 0.5 * (lo[p:] + hi[p:]).reshape(K, nf)
        half = 0.5 * (hi[p:] - lo[p:]).reshape(K, nf)
        ok = half > 0
        u = np.where(ok, (zq - mid) / np.where(ok, half, 1.0), 0.0)
        count = max(int(ok.sum()), 1)
        values["limits"] = float(np.sum(u * u) / count)
        g = np.zeros(problem.size)
        g[p:] = (2.0 * u / np.where(ok, half, 1.0) / count).ravel()
        grads["limits"] = g
    if "bounds" in names:
        lo_d, hi_d = problem.declared_bounds
        span = hi_d - lo_d
        ok = span > 0
        u = np.where(ok, (design - lo_d) / np.where(ok, span, 1.0), 0.5)
        below = np.maximum(0.0, margin - u)
        above = np.maximum(0.0, u - 1.0 + margin)
        m2 = margin * margin
        values["bounds"] = float(np.sum(below * below + above * above) / m2)
        g = np.zeros(problem.size)
        g[:p] = np.where(ok, 2.0 * (above - below) / np.where(ok, span, 1.0) / m2, 0.0)
        grads["bounds"] = g
    if "clearance" in names:
        values["clearance"], grads["clearance"] = soft_clearance(
            problem, z, bodies, clearance_temperature
        )
    return Terms(values, grads, lcis)


def designable_terms(bodies: ClearanceModel, dims: NDArray[np.int64]) -> NDArray[np.bool_]:
    """``(K, m)``: which clearance terms a design can change (module docstring): all
    but a body-vs-environment term whose anchors are fixed to the tool
    (``clearance.task_fixed_frames``) at a 6-D pose."""
    fixed_frames = set(task_fixed_frames(bodies.robot))
    fixed = []
    if bodies.envelope is not None:
        for part in bodies.parts:
            for e in part.env_ends:
                a = bodies.anchors[e]
                fixed.append(a.frame in fixed_frames and a.elbow < 0)
    fixed += [False] * (len(bodies.labels) - len(fixed))
    out = ~(np.asarray(dims)[:, None] == 6) | ~np.array(fixed, dtype=np.bool_)[None, :]
    return np.asarray(out, dtype=np.bool_)


def smallest_designable(bodies: ClearanceModel, problem: SynthesisProblem, z: Array) -> float:
    """The smallest clearance term a design can change at ``z`` (``designable_terms``;
    ``inf`` without one): the ``clearance`` objective's true value."""
    d = bodies.terms(problem, z).distance[designable_terms(bodies, problem.task.dims)]
    return float(d.min()) if d.size else math.inf


def soft_clearance(
    problem: SynthesisProblem, z: Array, bodies: ClearanceModel | None, temperature: float
) -> tuple[float, Array]:
    """The ``clearance`` term (module docstring): ``−τ log Σ exp(−d_i / τ)`` over every
    clearance term of every pose a design can change (``designable_terms``), and its
    gradient w.r.t. ``z``."""
    if bodies is None:
        raise InputError(
            problem.template.name,
            "design.bodies",
            "the clearance objective needs the template's bodies (design.bodies)",
        )
    t = bodies.terms(problem, z)
    mask = designable_terms(bodies, problem.task.dims)
    if not mask.any():
        raise InputError(
            problem.template.name, "design.bodies", "no clearance term a design can change"
        )
    x = np.where(mask, -t.distance / temperature, -np.inf)
    mx = float(x.max())
    ex = np.exp(x - mx)
    total = float(ex.sum())
    w = ex / total  # (K, m): the softmax weights
    g = np.empty(problem.size)
    g[: problem.p] = np.einsum("km,kma->a", w, t.grad_design)
    g[problem.p :] = np.einsum("km,kma->ka", w, t.grad_joints).ravel()
    return float(-temperature * (mx + math.log(total))), g


@dataclass(frozen=True)
class Objective:
    """Weights of the terms, each term's reference magnitude and the options
    (``bodies``: the clearance model the ``clearance`` term measures; ``keep``: the
    indices the improvement must not make worse than at its start, ``keep``).

    ``cost`` is ``Σ w_i s_i f_i / f_i⁰`` (module docstring), to be minimized. ``levels``
    (for ε-constraint Pareto points, ``pareto``) bound terms as well: a term to maximize
    at least at its level, one to minimize at most, enforced by the quadratic penalty
    ``penalty · (violation / f_i⁰)²``."""

    weights: Mapping[str, float]
    reference: Mapping[str, float] = field(default_factory=dict)
    margin: float = 0.05
    kci_temperature: float = 0.002
    levels: Mapping[str, float] = field(default_factory=dict)
    penalty: float = 30.0
    bodies: ClearanceModel | None = field(default=None, compare=False, repr=False)
    keep: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "weights", check_objective(self.weights))
        if not 0 < self.margin < 0.5:
            raise InputError("objective", "margin", f"must lie in (0, 0.5), got {self.margin}")
        for n in self.levels:
            if n not in OBJECTIVES:
                raise UnknownName("objective", "level", str(n), OBJECTIVES)
        for n in self.keep:
            if n not in OBJECTIVES:
                raise UnknownName("objective", "keep", str(n), OBJECTIVES)

    @property
    def names(self) -> tuple[str, ...]:
        """The weighted terms."""
        return tuple(n for n, w in self.weights.items() if w > 0)

    def terms(self, problem: SynthesisProblem, z: Array) -> Terms:
        names = tuple(dict.fromkeys((*self.names, *self.levels)))
        return evaluate_terms(
            problem, z, names, self.margin, self.kci_temperature, bodies=self.bodies
        )

    def referenced(self, terms: Terms) -> Objective:
        """This objective with the reference magnitudes taken from ``terms`` (1 where a
        term is 0: ``bounds`` inside its band, ``size`` of a zero-length design)."""
        ref = {n: (abs(v) if abs(v) > 1e-12 else 1.0) for n, v in terms.values.items()}
        return replace(self, reference=ref)

    def _factor(self, name: str) -> float:
        return -OBJECTIVES[name] * self.weights[name] / self.reference.get(name, 1.0)

    def _violation(self, name: str, value: float) -> float:
        """How far (in reference units) a term is on the wrong side of its level."""
        v = -OBJECTIVES[name] * (value - self.levels[name])  # > 0 when violated
        return max(0.0, v) / self.reference.get(name, 1.0)

    def cost(self, terms: Terms) -> float:
        c = sum(self._factor(n) * terms.values[n] for n in self.names)
        c += sum(self.penalty * self._violation(n, terms.values[n]) ** 2 for n in self.levels)
        return float(c)

    def slopes(self, terms: Terms) -> dict[str, float]:
        """``∂ cost / ∂ f_i`` for every term in the cost (weighted or levelled) at
        ``terms``: the weight factor plus the level penalty's derivative."""
        out = {n: self._factor(n) for n in self.names}
        for n in self.levels:
            v = self._violation(n, terms.values[n])
            if v > 0:
                scale = -OBJECTIVES[n] / self.reference.get(n, 1.0)
                out[n] = out.get(n, 0.0) + 2.0 * self.penalty * v * scale
        return out

    def gradient(self, terms: Terms) -> Array:
        g = np.zeros_like(next(iter(terms.gradients.values())))
        for n, s in self.slopes(terms).items():
            g = g + s * terms.gradients[n]
        return np.asarray(g, dtype=np.float64)
