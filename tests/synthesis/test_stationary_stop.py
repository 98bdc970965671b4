"""The ``dls`` solver stops at a constrained stationary point of its merit.

The projected gradient is checked against central finite differences of the merit, a
variable at a bound against the sign rule, and the stop on a task that no design can
serve (one pose 6 m beyond the others): it ends well before the stall limit, at the
merit and with the poses reached that the run without the stationary test ends at."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from reachwise.synthesis.clearance_rows import merit, stacked_rows
from reachwise.synthesis.init import initial_guess
from reachwise.synthesis.problem import SynthesisProblem
from reachwise.synthesis.solvers import (
    SolverOptions,
    projected_gradient,
    row_weights,
    solve_dls,
)
from reachwise.tasks.task import Task
from tests.synthesis.conftest import recovery_task, sb60


def _problem(k: int = 5, far: bool = False) -> SynthesisProblem:
    robot = sb60()
    task, _, _ = recovery_task(robot, np.random.default_rng(31), k)
    if far:  # the last pose 6 m out: no design within the bounds reaches it
        P = task.positions.copy()
        P[-1] += np.array([6.0, 0.0, 0.0])
        task = Task.from_arrays("far", P, rotations=task.rotations, dims=6)
    return SynthesisProblem(robot, task)


def _merit_gradient(prob: SynthesisProblem, z: np.ndarray, h: float = 1e-6) -> np.ndarray:
    wx = row_weights(prob)
    g = np.empty(z.size)
    for i in range(z.size):
        dz = np.zeros(z.size)
        dz[i] = h
        up = merit(prob, prob.evaluate(z + dz), wx, z + dz, None)
        down = merit(prob, prob.evaluate(z - dz), wx, z - dz, None)
        g[i] = (up - down) / (2 * h)
    return g


def test_projected_gradient_is_the_merit_gradient_with_the_bounds_sign_rule() -> None:
    prob = _problem()
    lo, hi = prob.bounds
    rng = np.random.default_rng(3)
    z = lo + (hi - lo) * rng.uniform(0.2, 0.8, lo.size)
    z = np.where(hi > lo, z, lo)
    wx = row_weights(prob)
    fd = _merit_gradient(prob, z)
    free = hi > lo
    g = projected_gradient(prob, z, stacked_rows(prob, prob.evaluate(z), wx, z, None))
    scale = float(np.max(np.abs(fd)))
    assert np.max(np.abs(g[free] - fd[free])) <= 1e-6 * scale
    assert np.all(g[~free] == 0.0)
    # put four free variables at a bound each: the component is 0 exactly when the
    # descent −g would push that variable out of its range
    idx = np.flatnonzero(free)[[0, 2, prob.p, prob.p + 3]]
    zb = z.copy()
    for n, i in enumerate(idx):
        zb[i] = lo[i] if n % 2 == 0 else hi[i]
    fd_b = _merit_gradient(prob, zb)
    g_b = projected_gradient(prob, zb, stacked_rows(prob, prob.evaluate(zb), wx, zb, None))
    for n, i in enumerate(idx):
        outward = fd_b[i] > 0 if n % 2 == 0 else fd_b[i] < 0
        assert (g_b[i] == 0.0) == outward
        if not outward:
            assert abs(g_b[i] - fd_b[i]) <= 1e-6 * float(np.max(np.abs(fd_b)))


def test_a_task_no_design_serves_stops_at_its_stationary_point() -> None:
    prob = _problem(far=True)
    rng = np.random.default_rng(0)
    z0 = initial_guess(prob, rng).z
    opt = SolverOptions(stationary_without_clearance=True)  # a reach-only task
    stop = solve_dls(prob, z0, opt, rng=np.random.default_rng(0))
    # the same run without the stationary test: only the stall limit ends it
    never = replace(opt, stationary_gradient=0.0)
    full = solve_dls(prob, z0, never, rng=np.random.default_rng(0))
    assert not stop.converged and not full.converged
    assert stop.iterations < full.iterations
    default = solve_dls(prob, z0, SolverOptions(), rng=np.random.default_rng(0))
    assert default.iterations == full.iterations  # reach-only runs: the stall rule alone
    assert stop.iterations % opt.reseed_every == 0  # stopped at the end of a window
    # the stop cut nothing that was still improving: the same merit within 1e-3
    assert stop.cost_history[-1] <= full.cost_history[-1] * (1 + 1e-3)
    wx = row_weights(prob)
    rows = stacked_rows(prob, stop.evaluation, wx, stop.z, None)
    g = projected_gradient(prob, stop.z, rows)
    assert np.max(np.abs(g)) <= opt.stationary_gradient * np.sqrt(2 * rows.cost)
    pos, ori, _ = prob.point_status(stop.evaluation)
    pos_f, ori_f, _ = prob.point_status(full.evaluation)
    assert np.array_equal(pos & ori, pos_f & ori_f)
    assert not (pos & ori)[-1]
