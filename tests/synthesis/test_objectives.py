"""Design objectives: exact gradients (central differences), weights, parsing, bound flags."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from reachwise import load_robot, load_task, synthesize
from reachwise.errors import InputError
from reachwise.kinematics.indices import gci, kci, lci
from reachwise.synthesis.bound_hits import bound_hits
from reachwise.synthesis.clearance import ClearanceModel
from reachwise.synthesis.objectives import (
    OBJECTIVES,
    Objective,
    check_objective,
    designable_terms,
    evaluate_terms,
    parse_objective,
)
from reachwise.synthesis.problem import SynthesisProblem

H = 1e-6


def small_problem(min_length: float = 0.0) -> SynthesisProblem:
    robot = load_robot("sb60")
    robot = replace(robot, design=replace(robot.design, min_length=min_length))
    task = load_task("tunnel-87").subset(np.arange(0, 87, 15), name="tunnel-87")
    return SynthesisProblem(robot, task)


def some_z(problem: SynthesisProblem, rng: np.random.Generator) -> np.ndarray:
    """A vector inside the bounds; a few design parameters inside the bound margin band
    (where the ``bounds`` term is active), none on a kink of it."""
    lo, hi = problem.bounds
    u = rng.uniform(0.2, 0.8, problem.size)
    u[[0, 3]] = (0.021, 0.973)
    return lo + (hi - lo) * u


def central(f, z: np.ndarray) -> np.ndarray:  # type: ignore[no-untyped-def]
    g = np.empty_like(z)
    for i in range(z.size):
        e = np.zeros_like(z)
        e[i] = H
        g[i] = (f(z + e) - f(z - e)) / (2 * H)
    return g


def bodies_of(prob: SynthesisProblem) -> ClearanceModel:
    """The sb60 stand-in bodies against the tunnel (every clearance term)."""
    return ClearanceModel(prob.template, prob.task.envelope, 0.1)


@pytest.mark.parametrize("name", list(OBJECTIVES))
def test_each_objective_gradient_equals_central_differences(
    name: str, rng: np.random.Generator
) -> None:
    prob = small_problem()
    z = some_z(prob, rng)
    bodies = bodies_of(prob)
    terms = evaluate_terms(prob, z, [name], bodies=bodies)
    grad = terms.gradients[name]

    def f(x: np.ndarray) -> float:
        return evaluate_terms(prob, x, [name], bodies=bodies).values[name]

    num = central(f, z)
    assert np.abs(num).max() > 0  # the term depends on z here
    assert np.abs(grad - num).max() <= 1e-6 * np.abs(num).max(), name


def test_weighted_objective_gradient_and_sign(rng: np.random.Generator) -> None:
    prob = small_problem()
    z = some_z(prob, rng)
    obj = Objective({"gci": 1.0, "kci": 0.5, "size": 0.2, "limits": 0.1, "bounds": 0.3})
    obj = obj.referenced(obj.terms(prob, z))
    num = central(lambda x: obj.cost(obj.terms(prob, x)), z)
    grad = obj.gradient(obj.terms(prob, z))
    assert np.abs(grad - num).max() <= 1e-6 * np.abs(num).max()
    # referenced at z: each term counts -1 (maximize) or +1 (minimize) times its weight
    assert obj.cost(obj.terms(prob, z)) == pytest.approx(-1.0 - 0.5 + 0.2 + 0.1 + 0.3)


def test_terms_agree_with_the_indices(rng: np.random.Generator) -> None:
    prob = small_problem()
    z = some_z(prob, rng)
    design, Q = prob.split(z)
    lcis = lci(prob.robot_at(design), Q)
    bodies = bodies_of(prob)
    t = evaluate_terms(prob, z, list(OBJECTIVES), kci_temperature=1e-5, bodies=bodies)
    assert t.values["gci"] == pytest.approx(gci(lcis), rel=1e-12)
    # the smooth minimum lies between the minimum and the minimum + τ log K
    assert kci(lcis) - 1e-12 <= t.values["kci"] <= kci(lcis) + 1e-5 * np.log(len(lcis))
    size = sum(abs(design[i]) for i, n in enumerate(prob.design_names) if n[0] in "ad")
    assert t.values["size"] == pytest.approx(size, abs=1e-3)
    # the clearance's soft minimum over the terms a design can change: between
    # min - τ log N and their true minimum
    d = bodies.terms(prob, z).distance[designable_terms(bodies, prob.task.dims)]
    tau = 0.005
    assert d.min() - tau * np.log(d.size) - 1e-12 <= t.values["clearance"] <= d.min() + 1e-12


def test_clearance_objective_over_hand_made_terms() -> None:
    """The soft minimum of the clearance terms against its formula, computed here from
    the terms themselves, and its limit as the temperature falls: the true minimum."""
    prob = small_problem()
    rng = np.random.default_rng(3)
    z = some_z(prob, rng)
    bodies = bodies_of(prob)
    d = bodies.terms(prob, z).distance[designable_terms(bodies, prob.task.dims)]
    for tau in (0.05, 0.005, 1e-4):
        got = evaluate_terms(prob, z, ["clearance"], bodies=bodies, clearance_temperature=tau)
        want = -tau * np.log(np.sum(np.exp(-(d - d.min()) / tau))) + d.min()
        assert got.values["clearance"] == pytest.approx(want, rel=1e-12, abs=1e-12)
    assert got.values["clearance"] == pytest.approx(d.min(), abs=1e-4 * np.log(d.size))
    with pytest.raises(InputError, match="bodies"):
        evaluate_terms(prob, z, ["clearance"])


def test_parse_and_check() -> None:
    assert parse_objective("gci:1,size:0.2") == {"gci": 1.0, "size": 0.2}
    assert parse_objective("kci") == {"kci": 1.0}
    assert check_objective(None) == {} == check_objective({})
    with pytest.raises(InputError, match=r"speed.*valid: bounds, clearance, gci"):
        parse_objective("speed:1")
    with pytest.raises(InputError, match="not a number"):
        parse_objective("gci:x")
    with pytest.raises(InputError, match=">= 0"):
        check_objective({"gci": -1})
    with pytest.raises(InputError, match="positive"):
        check_objective({"gci": 0.0})
    with pytest.raises(InputError, match="margin"):
        Objective({"gci": 1.0}, margin=0.6)


def test_min_length_tightens_the_kept_bounds_and_flags() -> None:
    prob = small_problem(min_length=0.2)
    lo, hi = prob.design_bounds
    decl_lo, decl_hi = prob.declared_bounds
    for i, name in enumerate(prob.design_names):
        if name[0] in "ad":
            assert lo[i] == max(decl_lo[i], 0.2)
        else:
            assert lo[i] == decl_lo[i]
    assert np.array_equal(hi, decl_hi)
    with pytest.raises(InputError, match="min_length"):
        small_problem(min_length=0.7).design_bounds  # noqa: B018  (a2 lies in [0, 0.5])
    # a design on its bounds is flagged by side; one inside is not
    d = 0.5 * (lo + hi)
    d[0], d[1], d[-1] = lo[0], lo[1] + 0.004 * (decl_hi[1] - decl_lo[1]), hi[-1]
    hits = {h.parameter: h.side for h in bound_hits(prob, d)}
    assert hits == {"a1": "min_length", "a2": "min_length", "base.z": "upper"}
    d[1] = lo[1] + 0.02 * (decl_hi[1] - decl_lo[1])  # 2 % inside: not flagged
    assert "a2" not in {h.parameter for h in bound_hits(prob, d)}


def test_terms_no_design_changes_are_those_the_pose_places() -> None:
    """At a reaching design, each term left out of the clearance objective (the feed,
    fixed to the tool, against the tunnel at a 6-D pose) equals the feed's distance
    placed by the task pose alone, written out here; every other term is kept."""
    prob = small_problem()
    res = synthesize(prob.task, prob.template, runs=1, seed=0)
    assert res.reached.all()
    bodies = bodies_of(prob)
    z = prob.pack(res.best.design, res.best.q)
    d = bodies.terms(prob, z).distance
    mask = designable_terms(bodies, prob.task.dims)
    robot = prob.template
    feed = next(b for b in robot.design.bodies if b.name == "feed")
    f = robot.link_names.index(feed.link)
    F0 = np.asarray(robot.fk_all(np.zeros(robot.n)))
    tool_in_f = np.linalg.inv(F0[f]) @ F0[-1]
    s, e = np.array(feed.start), np.array(feed.end)
    e = e - feed.contact * (e - s) / np.linalg.norm(e - s)
    env = prob.task.envelope
    assert env is not None
    fixed_cols = np.flatnonzero(~mask[0])
    assert (prob.task.dims == 6).all() and fixed_cols.size == 2  # the feed's two ends
    for k in range(prob.K):
        Tf = prob.task.poses[k] @ np.linalg.inv(tool_in_f)
        ends = np.stack([Tf[:3, :3] @ s + Tf[:3, 3], Tf[:3, :3] @ e + Tf[:3, 3]])
        want = np.sort(env.signed_distance(ends) - feed.radius)
        assert np.allclose(np.sort(d[k, fixed_cols]), want, atol=5e-3)  # pose within 1 mm, 1 mrad
    assert mask.sum() == mask.size - prob.K * fixed_cols.size
