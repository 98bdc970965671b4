"""The record of one simulation run: :class:`SimulationLog` (time, joints, commands,
tool poses, every pair's distance, statuses, events, goals) with its figures' data,
``save`` to a folder and :func:`load_log` back."""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError
from reachwise.io.atomic import atomic_open, atomic_write
from reachwise.io.ros.joint_state import robot_joint_names
from reachwise.kinematics.robot import Robot
from reachwise.sim.robots import robot_of
from reachwise.sim.scenarios import Scenario, load_scenario

__all__ = ["Event", "GoalRecord", "SimulationLog", "joint_names_of", "load_log"]


@dataclass(frozen=True)
class Event:
    """Something that happened at time ``t`` (s) to ``robot`` (or ``""``)."""

    t: float
    robot: str
    kind: str
    text: str


@dataclass(frozen=True)
class GoalRecord:
    """One goal of one robot: when it was reached (``None``: never) and the remaining
    errors at the end of the run or when reached."""

    robot: str
    index: int
    name: str
    work: float
    reached_at: float | None
    position_error: float
    orientation_error: float


@dataclass(frozen=True, eq=False)
class SimulationLog:
    """Everything a run recorded, one row per tick.

    ``t`` (T,); per robot (dicts keyed by robot name): ``q``, ``qdot`` (actual),
    ``command`` (T, n), ``tool`` (T, 4, 4), ``state`` (T,) strings, ``goal_index``
    (T,); per pair (``pairs`` names ``"a|b"``): ``distance`` (T, P) cloud distance
    (``inf`` beyond margin + monitor range), ``signed`` (T, P) the same or ``−depth``
    when the solids overlap, ``margins`` (P,) the collision margins ρ_O. ``events``,
    ``goals``; ``first_collision`` (s) and its pair, or ``None``. ``object_poses``:
    per moving object (``motion``), its world pose at each tick (T, 4, 4), for replay.
    ``true_pairs`` (``"robot/link|object"``) and ``true_distance`` (T, Q): the signed
    distance of each robot link's true surface to each object outside the scene
    (``scene: false``: seen only by sensors), exact (``reachwise.sim.contact``),
    ``inf`` beyond margin + monitor range. ``frames``: per sensor, the index of the
    frame in the scene at each tick (T,), for replay (``reachwise.sim.sensors``).
    ``joint_names``: per robot, the name of each entry of ``q`` (its URDF or robot
    file's joint names, ``reachwise.io.ros.joint_state.robot_joint_names``); the
    CSV's joint columns are ``<robot>.<joint name>`` (``<robot>.q<k>`` without names).
    """

    scenario: str
    avoidance: bool
    dt: float
    t: NDArray[np.float64]
    robots: tuple[str, ...]
    q: dict[str, NDArray[np.float64]]
    qdot: dict[str, NDArray[np.float64]]
    command: dict[str, NDArray[np.float64]]
    tool: dict[str, NDArray[np.float64]]
    state: dict[str, NDArray[np.str_]]
    goal_index: dict[str, NDArray[np.int64]]
    pairs: tuple[str, ...]
    distance: NDArray[np.float64]
    signed: NDArray[np.float64]
    margins: NDArray[np.float64]
    lower: dict[str, NDArray[np.float64]]
    upper: dict[str, NDArray[np.float64]]
    vmax: dict[str, NDArray[np.float64]]
    events: tuple[Event, ...] = ()
    goals: tuple[GoalRecord, ...] = ()
    first_collision: float | None = None
    first_collision_pair: str | None = None
    extras: dict[str, Any] = field(default_factory=dict)
    object_poses: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    true_pairs: tuple[str, ...] = ()
    true_distance: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 0)))
    frames: dict[str, NDArray[np.int64]] = field(default_factory=dict)
    joint_names: dict[str, tuple[str, ...]] = field(default_factory=dict)

    def joint_columns(self, robot: str) -> list[str]:
        """The CSV columns of ``robot``'s joints: ``<robot>.<joint name>``, or
        ``<robot>.q<k>`` (k from 1) when the log has no names for it."""
        n = self.q[robot].shape[1] if self.q[robot].ndim == 2 else 0
        names = self.joint_names.get(robot, ())
        if len(names) != n:
            names = tuple(f"q{k + 1}" for k in range(n))
        return [f"{robot}.{name}" for name in names]

    @property
    def min_true_distance(self) -> NDArray[np.float64]:
        """Smallest true signed distance over ``true_pairs`` at each tick (inf without)."""
        if self.true_distance.ndim != 2 or self.true_distance.shape[1] == 0:
            return np.full(self.t.shape, np.inf)
        return np.asarray(self.true_distance.min(axis=1))

    @property
    def min_distance(self) -> NDArray[np.float64]:
        """Smallest signed distance over all pairs at each tick (inf without pairs)."""
        if self.signed.shape[1] == 0:
            return np.full(self.t.shape, np.inf)
        return np.asarray(self.signed.min(axis=1))

    @property
    def closest_pair(self) -> NDArray[np.str_]:
        """The pair (``"a|b"``) with the smallest signed distance at each tick (``""``
        without pairs or when every pair is beyond range)."""
        if self.signed.shape[1] == 0:
            return np.full(self.t.shape, "", dtype=np.str_)
        names = np.array([*self.pairs, ""], dtype=np.str_)
        k = np.argmin(self.signed, axis=1)
        k = np.where(np.isfinite(self.signed[np.arange(k.size), k]), k, len(self.pairs))
        return names[k]

    def first_contact(self) -> tuple[float, str] | None:
        """The first tick whose signed distance is ≤ 0 for some pair (the solids
        overlap or the clouds touch): its time and the first such pair; else None."""
        hit = self.signed <= 0.0
        ticks = np.flatnonzero(hit.any(axis=1))
        if ticks.size == 0:
            return None
        k = int(ticks[0])
        return float(self.t[k]), self.pairs[int(np.argmax(hit[k]))]

    @property
    def all_goals_reached(self) -> bool:
        return all(g.reached_at is not None for g in self.goals)

    def limit_violations(self, tol: float = 1e-9) -> dict[str, NDArray[np.bool_]]:
        """Per robot, ``(T, n)``: True where joint ``j`` at tick ``k`` breaks its limits.

        A joint inside ``[lower, upper]`` must stay inside (within ``tol``). A joint
        that starts outside may only move back inward: its violation (how far it is
        outside) may never exceed the smallest violation it has had so far by more
        than ``tol`` — it must not move farther out, and once back inside it must stay
        inside."""
        out = {}
        for r in self.robots:
            q = np.asarray(self.q[r], dtype=float)
            lo = np.asarray(self.lower[r], dtype=float)
            hi = np.asarray(self.upper[r], dtype=float)
            outside = np.maximum(np.maximum(q - hi, lo - q), 0.0)  # (T, n), 0 inside
            if outside.shape[0] == 0:
                out[r] = np.zeros(outside.shape, dtype=bool)
                continue
            best = np.minimum.accumulate(outside, axis=0)  # smallest violation so far
            allowed = np.vstack([outside[:1], best[:-1]])  # the start is what it is
            out[r] = outside > allowed + tol
        return out

    def limits_held(self, tol: float = 1e-9) -> dict[str, bool]:
        """Per robot: every joint inside its limits at every tick (a joint that starts
        outside must move monotonically back inward: never farther out, and once inside
        it stays inside; see :meth:`limit_violations`)."""
        return {r: not bool(v.any()) for r, v in self.limit_violations(tol).items()}

    def speed_violations(self, tol: float = 1e-9) -> dict[str, NDArray[np.bool_]]:
        """Per robot, ``(T, n)``: True where the commanded or the actual speed of joint
        ``j`` at tick ``k`` exceeds its ``v_max`` by more than ``tol``."""
        return {
            r: (np.abs(self.command[r]) > self.vmax[r] + tol)
            | (np.abs(self.qdot[r]) > self.vmax[r] + tol)
            for r in self.robots
        }

    def speeds_held(self, tol: float = 1e-9) -> dict[str, bool]:
        """Per robot: ``|command|`` and ``|actual velocity|`` ≤ ``v_max`` at every tick."""
        return {r: not bool(v.any()) for r, v in self.speed_violations(tol).items()}

    def summary(self) -> dict[str, Any]:
        """A JSON-ready summary of the outcome."""
        md = self.min_distance
        finite = md[np.isfinite(md)]
        per_pair = {
            p: float(np.min(self.signed[:, i])) if self.signed.shape[0] else math.inf
            for i, p in enumerate(self.pairs)
        }
        stalls = [e for e in self.events if e.kind == "stalled"]
        return {
            "scenario": self.scenario,
            "avoidance": self.avoidance,
            "dt": self.dt,
            "duration": float(self.t[-1]) if self.t.size else 0.0,
            "ticks": int(self.t.size),
            "all_goals_reached": self.all_goals_reached,
            "goals": [
                {
                    "robot": g.robot,
                    "index": g.index,
                    "name": g.name,
                    "work": g.work,
                    "reached_at": g.reached_at,
                    "position_error": g.position_error,
                    "orientation_error": g.orientation_error,
                }
                for g in self.goals
            ],
            "min_distance": float(finite.min()) if finite.size else None,
            "min_distance_by_pair": {
                k: (v if math.isfinite(v) else None) for k, v in per_pair.items()
            },
            "first_collision": self.first_collision,
            "first_collision_pair": self.first_collision_pair,
            **self._true_summary(),
            "limits_held": self.limits_held(),
            "speeds_held": self.speeds_held(),
            "stalls": [{"t": e.t, "robot": e.robot, "text": e.text} for e in stalls],
            "extras": self.extras,
            "events": [
                {"t": e.t, "robot": e.robot, "kind": e.kind, "text": e.text} for e in self.events
            ],
        }

    def _true_summary(self) -> dict[str, Any]:
        """The true clearances of the summary (only for a run that has them)."""
        if not self.true_pairs:
            return {}
        md = self.min_true_distance
        finite = md[np.isfinite(md)]
        return {
            "min_true_distance": float(finite.min()) if finite.size else None,
            "min_true_distance_by_pair": {
                p: (float(v) if math.isfinite(v) else None)
                for p, v in zip(self.true_pairs, self.true_distance.min(axis=0), strict=True)
            }
            if self.t.size
            else {},
        }

    def save(self, folder: str | Path) -> Path:
        """Write ``log.npz`` (every array), ``log.csv`` (t, joints by name, tool xyz, min
        distance per tick) and ``summary.json`` into ``folder``; returns it."""
        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        arrays: dict[str, Any] = {
            "t": self.t,
            "distance": self.distance,
            "signed": self.signed,
            "margins": self.margins,
            "pairs": np.array(self.pairs, dtype=str),
            "min_distance": self.min_distance,
        }
        for r in self.robots:
            arrays[f"{r}.q"] = self.q[r]
            arrays[f"{r}.qdot"] = self.qdot[r]
            arrays[f"{r}.command"] = self.command[r]
            arrays[f"{r}.tool"] = self.tool[r]
            arrays[f"{r}.state"] = self.state[r]
            arrays[f"{r}.goal_index"] = self.goal_index[r]
            if r in self.joint_names:
                arrays[f"{r}.joint_names"] = np.array(self.joint_names[r], dtype=str)
        for name, poses in self.object_poses.items():
            arrays[f"object.{name}.pose"] = poses
        if self.true_pairs:
            arrays["true_pairs"] = np.array(self.true_pairs, dtype=str)
            arrays["true_distance"] = self.true_distance
        for name, frames in self.frames.items():
            arrays[f"sensor.{name}.frame"] = frames
        with atomic_open(out / "log.npz", "wb") as npz:
            np.savez_compressed(npz, **arrays)
        with atomic_open(out / "log.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            head = ["t"]
            for r in self.robots:
                head += self.joint_columns(r)
                head += [f"{r}.tool_{c}" for c in "xyz"] + [f"{r}.state"]
            head.append("min_distance")
            w.writerow(head)
            md = self.min_distance
            for i in range(self.t.size):
                row: list[Any] = [f"{self.t[i]:.4f}"]
                for r in self.robots:
                    row += [f"{v:.6g}" for v in self.q[r][i]]
                    row += [f"{v:.6g}" for v in self.tool[r][i, :3, 3]]
                    row.append(self.state[r][i])
                row.append(f"{md[i]:.6g}")
                w.writerow(row)
        atomic_write(out / "summary.json", json.dumps(self.summary(), indent=2))
        return out


def joint_names_of(robots: dict[str, Robot]) -> dict[str, tuple[str, ...]]:
    """Each robot's joint names, by robot name (what :attr:`SimulationLog.joint_names`
    holds: ``reachwise.io.ros.joint_state.robot_joint_names``)."""
    return {name: robot_joint_names(r) for name, r in robots.items()}


def load_log(folder: str | Path, scenario: Scenario | str | Path | None = None) -> SimulationLog:
    """Read a log written by :meth:`SimulationLog.save` (``log.npz`` and
    ``summary.json`` in ``folder``) back into a :class:`SimulationLog`.

    The joint limits and speed bounds come from ``log.npz`` when it has them
    (``<robot>.lower``, ``.upper``, ``.vmax``), else from the robots of ``scenario``
    (default: the scenario the log names, when it is a built-in one); without either
    they are unbounded (``±inf``) and ``extras["limits"]`` says so. Missing or
    unreadable files raise :class:`~reachwise.errors.InputError` naming the file.
    """
    meta, arrays = _read_log_files(Path(folder))
    robots = tuple(k[: -len(".q")] for k in arrays if k.endswith(".q"))
    per = _per_robot(arrays, robots, str(Path(folder) / "log.npz"))
    extras: dict[str, Any] = dict(meta.get("extras") or {})
    lower, upper, vmax = _limits(arrays, robots, per["q"], _log_robots(meta, scenario), extras)
    fc = meta.get("first_collision")
    return SimulationLog(
        scenario=str(meta["scenario"]),
        avoidance=bool(meta["avoidance"]),
        dt=float(meta["dt"]),
        t=arrays["t"],
        robots=robots,
        q=per["q"],
        qdot=per["qdot"],
        command=per["command"],
        tool=per["tool"],
        state=per["state"],
        goal_index=per["goal_index"],
        pairs=tuple(str(p) for p in arrays["pairs"]),
        distance=arrays["distance"],
        signed=arrays["signed"],
        margins=arrays["margins"],
        lower=lower,
        upper=upper,
        vmax=vmax,
        events=tuple(
            Event(float(e["t"]), str(e["robot"]), str(e["kind"]), str(e["text"]))
            for e in meta.get("events", [])
        ),
        goals=_goal_records(meta),
        first_collision=None if fc is None else float(fc),
        first_collision_pair=meta.get("first_collision_pair"),
        joint_names={
            r: tuple(str(x) for x in arrays[f"{r}.joint_names"])
            for r in robots
            if f"{r}.joint_names" in arrays
        },
        extras=extras,
        object_poses=_named(arrays, "object.", ".pose"),
        true_pairs=tuple(str(p) for p in arrays.get("true_pairs", ())),
        true_distance=arrays.get("true_distance", np.zeros((arrays["t"].size, 0))),
        frames=_named(arrays, "sensor.", ".frame"),
    )


def _read_log_files(src: Path) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
    """``summary.json`` and the arrays of ``log.npz`` in ``src``, each checked for the
    keys every log has; a missing or unreadable file or key is an ``InputError``."""
    npz_path, sum_path = src / "log.npz", src / "summary.json"
    for p in (npz_path, sum_path):
        if not p.is_file():
            raise InputError(str(p), "", "missing: not a simulation log folder")
    try:
        meta = json.loads(sum_path.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(str(sum_path), "", f"unreadable: {exc}") from None
    for key in ("scenario", "avoidance", "dt"):
        if not isinstance(meta, dict) or key not in meta:
            raise InputError(str(sum_path), key, "missing")
    try:
        with np.load(npz_path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, ValueError) as exc:
        raise InputError(str(npz_path), "", f"unreadable: {exc}") from None
    for key in ("t", "distance", "signed", "margins", "pairs"):
        if key not in arrays:
            raise InputError(str(npz_path), key, "missing")
    return meta, arrays


def _per_robot(
    arrays: dict[str, NDArray[Any]], robots: tuple[str, ...], source: str
) -> dict[str, dict[str, NDArray[Any]]]:
    """``{field: {robot: array}}`` of the per-robot arrays (``<robot>.<field>``)."""
    per: dict[str, dict[str, NDArray[Any]]] = {}
    for field_ in ("q", "qdot", "command", "tool", "state", "goal_index"):
        per[field_] = {}
        for r in robots:
            key = f"{r}.{field_}"
            if key not in arrays:
                raise InputError(source, key, "missing")
            per[field_][r] = arrays[key]
    return per


def _named(arrays: dict[str, NDArray[Any]], prefix: str, suffix: str) -> dict[str, NDArray[Any]]:
    """``{name: array}`` of the arrays keyed ``<prefix><name><suffix>``."""
    return {
        k[len(prefix) : -len(suffix)]: arrays[k]
        for k in arrays
        if k.startswith(prefix) and k.endswith(suffix)
    }


def _log_robots(meta: dict[str, Any], scenario: Scenario | str | Path | None) -> dict[str, Robot]:
    """The robots of ``scenario``, or of the built-in scenario the log names (none
    when it names no built-in one)."""
    from reachwise.sim.scenarios import builtin_scenarios

    sc: Scenario | None = None
    if scenario is not None:
        sc = load_scenario(scenario)
    elif meta["scenario"] in builtin_scenarios():
        sc = load_scenario(meta["scenario"])
    if sc is None:
        return {}
    return {rs.name: robot_of(rs, sc) for rs in sc.spec.robots}


def _limits(
    arrays: dict[str, NDArray[Any]],
    robots: tuple[str, ...],
    q: dict[str, NDArray[Any]],
    models: dict[str, Robot],
    extras: dict[str, Any],
) -> tuple[dict[str, NDArray[np.float64]], ...]:
    """Each robot's joint limits and speed bounds (lower, upper, vmax): saved in the
    log, else its model's in ``models``, else unbounded (noted in ``extras``)."""
    lower: dict[str, NDArray[np.float64]] = {}
    upper: dict[str, NDArray[np.float64]] = {}
    vmax: dict[str, NDArray[np.float64]] = {}
    for r in robots:
        n = q[r].shape[1] if q[r].ndim == 2 else 0
        model = models.get(r)
        if all(f"{r}.{k}" in arrays for k in ("lower", "upper", "vmax")):  # saved in the log
            lower[r], upper[r] = arrays[f"{r}.lower"], arrays[f"{r}.upper"]
            vmax[r] = arrays[f"{r}.vmax"]
        elif model is not None and model.n == n:
            lower[r], upper[r] = np.asarray(model.lower), np.asarray(model.upper)
            vmax[r] = np.asarray(model.vmax)
        else:
            lower[r], upper[r] = np.full(n, -np.inf), np.full(n, np.inf)
            vmax[r] = np.full(n, np.inf)
            extras["limits"] = "unknown: the log's scenario was not found; limits are ±inf"
    return lower, upper, vmax


def _goal_records(meta: dict[str, Any]) -> tuple[GoalRecord, ...]:
    """The goal records of ``summary.json``."""
    return tuple(
        GoalRecord(
            str(g["robot"]),
            int(g["index"]),
            str(g["name"]),
            float(g["work"]),
            None if g["reached_at"] is None else float(g["reached_at"]),
            float(g["position_error"]),
            float(g["orientation_error"]),
        )
        for g in meta.get("goals", [])
    )
