"""``reachwise bench synthesis``: the hard SB60 recovery instance, dls against scipy trf.

The instance (issue "Tasks and dimensional synthesis"): the ``sb60`` structure with the
true design (a1, a2, d3 offset, d4, a4, d6, d7) = (0.6, 1.2, 1.0, 0.4, 0.3, 0.5, 0.3) m
and base (0.5, 0, 1.2) m, 87 6-D poses from joints drawn uniformly over 90 % of each
joint's range, every design bound ±2 m. Each run starts from its own random initial
design (Beta sets seeded by IK, P-I §3.3); ``dls`` and ``trf`` start from the same
initial vector of a given seed, so the comparison isolates the solver.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from reachwise.benchmarks._harness import BenchReport, Target
from reachwise.io.robot_file import load_robot
from reachwise.kinematics.robot import DesignSpace
from reachwise.synthesis.init import initial_guess
from reachwise.synthesis.problem import SynthesisProblem
from reachwise.synthesis.solvers import solve_dls, solve_trf
from reachwise.tasks.task import Task

TRUE_DESIGN = np.array([0.6, 1.2, 1.0, 0.4, 0.3, 0.5, 0.3, 0.5, 0.0, 1.2])


def hard_instance(seed: int = 7, points: int = 87) -> SynthesisProblem:
    """The benchmark's problem: template with ±2 m bounds and ``points`` true poses (87;
    870 for the scaling figure)."""
    robot = load_robot("sb60")
    joints: dict[int, dict[str, tuple[float, float]]] = {}
    for kind, j, p in robot.design.free:
        if kind == "joint":
            joints.setdefault(j, {})[p] = (-2.0, 2.0)
    template = replace(
        robot, design=DesignSpace(joints=joints, base={c: (-2.0, 2.0) for c in "xyz"})
    )
    probe = SynthesisProblem(template, Task.from_arrays("probe", np.zeros((1, 3)), dims=3))
    if probe.design_names != ("a1", "a2", "d3", "d4", "a4", "d6", "d7", "base.x", "base.y",
                              "base.z"):  # fmt: skip
        raise RuntimeError(f"sb60 design variables changed: {probe.design_names}")
    rng = np.random.default_rng(seed)
    span = robot.upper - robot.lower
    Q = rng.uniform(robot.lower + 0.05 * span, robot.upper - 0.05 * span, (points, robot.n))
    T = probe.robot_at(TRUE_DESIGN).fk(Q)
    task = Task.from_arrays(f"sb60-hard-{points}", T[:, :3, 3], rotations=T[:, :3, :3], dims=6)
    return SynthesisProblem(template, task)


def run(quick: bool = False) -> BenchReport:
    rep = BenchReport("synthesis")
    prob = hard_instance()
    runs_dls = 3 if quick else 20
    runs_trf = 1 if quick else 5
    nfev = 200 if quick else 2000
    times = {"dls": [], "trf": []}  # type: dict[str, list[float]]
    reached = {"dls": [], "trf": []}  # type: dict[str, list[bool]]
    for seed in range(runs_dls):
        rng = np.random.default_rng(seed)
        t0 = time.perf_counter()
        guess = initial_guess(prob, rng)
        t_init = time.perf_counter() - t0
        out = solve_dls(prob, guess.z, rng=rng)
        times["dls"].append(time.perf_counter() - t0)
        reached["dls"].append(out.converged and prob.within_bounds(out.z))
        if seed < runs_trf:
            t1 = time.perf_counter()
            o2 = solve_trf(prob, guess.z, max_nfev=nfev)
            times["trf"].append(time.perf_counter() - t1 + t_init)
            reached["trf"].append(o2.converged and prob.within_bounds(o2.z))
    for m in ("dls", "trf"):
        t = np.array(times[m])
        rep.metrics[f"{m}.runs"] = float(t.size)
        rep.metrics[f"{m}.runs_reaching_all"] = float(np.sum(reached[m]))
        rep.metrics[f"{m}.success_rate"] = float(np.mean(reached[m]))
        rep.metrics[f"{m}.median_s"] = float(np.median(t))
        rep.metrics[f"{m}.p99_s"] = float(np.percentile(t, 99))
    rep.ratios["dls_over_trf_median_s"] = rep.metrics["dls.median_s"] / rep.metrics["trf.median_s"]
    rep.targets["dls_success_rate"] = Target(rep.metrics["dls.success_rate"], 0.9, True)
    rep.targets["dls_median_s"] = Target(rep.metrics["dls.median_s"], 10.0)
    rep.notes.append(
        f"{prob.K} poses, {prob.size} unknowns, {prob.residual_rows} residuals; both solvers "
        f"start from the same IK-seeded initial design per seed; trf max_nfev={nfev}; "
        "times include the initialization"
    )
    return rep
