"""Occlusion-aware P-V (issue 9, P-V Fig. 5): with the occlusion fill the return path
behind the obstacle is as clean as the outward path in front of it; without it, not."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import trimesh
from scipy.optimize import linprog
from scipy.spatial import ConvexHull

from reachwise.io.robot_file import load_robot
from reachwise.sim.log import SimulationLog
from reachwise.sim.p5_scenes import get_scene
from reachwise.sim.scenarios import load_scenario, scenario_from_dict
from reachwise.sim.simulate import simulate
from reachwise.sim.world import build_world

START = np.array([2.7, 1.5, 1.5])
GOAL = np.array([2.7, -1.5, 1.5])


def _variant(occlusion: dict | None):  # type: ignore[no-untyped-def,type-arg]
    sc = load_scenario("p5-crane-occlusion")
    data = copy.deepcopy(sc.spec.model_dump(by_alias=True, exclude_unset=True))
    data["objects"][0]["occlusion"] = occlusion
    if occlusion is None:
        del data["objects"][0]["occlusion"]
    return scenario_from_dict(data, sc.source, sc.folder)


def _legs(log: SimulationLog) -> dict[str, tuple[float, float]]:
    """Per leg: TCP path length and peak distance from the line start-goal."""
    tool = log.tool["crane"][:, :3, 3]
    gi = log.goal_index["crane"]
    d = (GOAL - START) / np.linalg.norm(GOAL - START)
    out = {}
    for name, idx in (("outward", (0, 1)), ("return", (2, 3))):
        p = tool[np.isin(gi, idx)]
        r = p - START
        dev = np.linalg.norm(r - np.outer(r @ d, d), axis=1).max()
        out[name] = (float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()), float(dev))
    return out


def _true_box_overlap(log: SimulationLog, sc) -> float:  # type: ignore[no-untyped-def]
    """How deep the real box and the grabber's solid overlap over the run (m; negative:
    never), independently of the simulator's own contact judge (``Solid.depth``): the
    grabber is the convex hull of its mesh (Qhull facets), placed by forward kinematics;
    at each tick a linear program finds the point of the real box deepest inside that
    hull, ``max t`` subject to ``n_i·x + c_i + t ≤ 0`` for every facet, ``lo ≤ x ≤ hi``
    (HiGHS). ``t > 0``: the solids overlap that deep; ``t < 0``: they are disjoint."""
    lo, hi = get_scene("p5-occlusion").obstacles[0]
    spec = next(r for r in sc.spec.robots if r.name == "crane")
    part = spec.link_clouds["link_6"]
    mesh = trimesh.load(str(sc.folder / part.mesh), force="mesh")
    mesh.apply_transform(part.pose.matrix())
    facets = ConvexHull(np.asarray(mesh.vertices)).equations  # n·x + c <= 0 inside, |n| = 1
    assert spec.base is None  # the crane stands where its robot file puts it
    robot = load_robot(spec.robot)
    link = robot.link_names.index("link_6")
    deepest = -np.inf
    for k in range(0, log.t.size, 5):
        F = robot.fk_all(log.q["crane"][k])[link]
        n = facets[:, :3] @ F[:3, :3].T  # facet normals in world
        c = facets[:, 3] - n @ F[:3, 3]
        res = linprog(
            [0.0, 0.0, 0.0, -1.0],
            A_ub=np.column_stack([n, np.ones(len(c))]),
            b_ub=-c,
            bounds=[*zip(lo, hi, strict=True), (None, None)],
        )
        assert res.status == 0, res.message
        deepest = max(deepest, -float(res.fun))
    return float(deepest)


@pytest.fixture(scope="module")
def runs() -> dict[str, tuple]:  # type: ignore[type-arg]
    out = {}
    for label, occ in (("fill", {"fill": True, "depth": 0.7}), ("plain", None)):
        sc = _variant(occ)
        out[label] = (sc, simulate(sc))
    return out


def test_builtin_has_the_fill_on() -> None:
    spec = load_scenario("p5-crane-occlusion").spec.objects[0]
    assert spec.occlusion is not None and spec.occlusion.fill and spec.occlusion.depth == 0.7


def test_with_the_fill_the_return_matches_the_outward_path(runs) -> None:  # type: ignore[no-untyped-def]
    sc, log = runs["fill"]
    assert log.all_goals_reached
    assert log.first_collision is None and log.min_distance.min() >= 0.02
    legs = _legs(log)
    for i in (0, 1):  # length, peak deviation
        assert abs(legs["return"][i] / legs["outward"][i] - 1.0) <= 0.2, legs
    assert _true_box_overlap(log, sc) < 0.0


def test_without_the_fill_the_return_cuts_behind_the_box(runs) -> None:  # type: ignore[no-untyped-def]
    sc, log = runs["plain"]
    assert log.all_goals_reached  # the scan shows nothing in its way
    legs = _legs(log)
    ratios = [legs["return"][i] / legs["outward"][i] - 1.0 for i in (0, 1)]
    assert max(abs(r) for r in ratios) > 0.2, legs
    assert ratios[1] < -0.2  # it passes much closer behind the box than in front
    assert _true_box_overlap(log, sc) > 0.0  # and its grabber enters the real box
    # the outward leg, in front of the scanned face, is the same either way
    fill_legs = _legs(runs["fill"][1])
    np.testing.assert_allclose(legs["outward"], fill_legs["outward"], rtol=0.02)


def test_figure_shows_both_legs_of_both_runs(runs, tmp_path) -> None:  # type: ignore[no-untyped-def]
    from reachwise.report.sim_plots import occlusion_paths_figure

    panels = []
    for label in ("plain", "fill"):
        sc, log = runs[label]
        cloud = build_world(sc).scene.objects["scan"].cloud.points
        panels.append((label, log, cloud))
    fig = occlusion_paths_figure(panels, obstacle=get_scene("p5-occlusion").obstacles[0])
    assert len(fig.axes) == 2
    for ax, (_, log, _) in zip(fig.axes, panels, strict=True):
        texts = [t.get_text() for t in ax.get_legend().get_texts()]
        legs = _legs(log)
        assert any(t.startswith(f"return: {legs['return'][0]:.2f} m") for t in texts), texts
    fig.savefig(tmp_path / "occlusion.png")
    assert (tmp_path / "occlusion.png").stat().st_size > 10_000
