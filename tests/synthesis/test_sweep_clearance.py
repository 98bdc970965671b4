"""The topology sweep with a clearance: runs keep the bodies clear, rank by the clearance,
reject what cannot be kept clear."""

from __future__ import annotations

import math

import numpy as np
import pytest

from reachwise import load_robot, load_task
from reachwise.synthesis.clearance import ClearanceModel, watched_pairs
from reachwise.synthesis.rank import Candidate, Measures, rank
from reachwise.synthesis.sweep import SweepConfig
from reachwise.synthesis.sweep.items import WorkItem, run_item
from reachwise.synthesis.topology import TemplateOptions
from reachwise.synthesis.topology.template import to_template
from reachwise.tasks.task import Task


def _m(clearance: float, mean: float = 0.1) -> Measures:
    return Measures(mean, mean, mean, 1.0, 3.0, 0, clearance=clearance)


def test_rank_by_clearance_higher_first() -> None:
    cands = [
        Candidate("a", 5, 5, _m(0.12)),
        Candidate("b", 5, 5, _m(0.31, mean=0.05)),
        Candidate("c", 4, 5, _m(0.9)),  # not every pose reached (or not clear): rejected
        Candidate("d", 5, 5, _m(0.2)),
    ]
    rows = rank(cands, "clearance")
    assert [(r.rank, r.candidate.name) for r in rows] == [(1, "b"), (2, "d"), (3, "a"), (None, "c")]
    assert math.isnan(Measures(0.1, 0.1, 0.1, 1.0, 1.0, 0).clearance)  # none kept
    with pytest.raises(Exception, match="clearance"):
        SweepConfig(clearance=-0.1)


def test_generated_templates_carry_stand_in_bodies() -> None:
    plain = to_template("RRPRR")
    assert plain.design.bodies == ()
    robot = to_template("RRPRR", TemplateOptions(body_radius=0.1))
    assert [b.link for b in robot.design.bodies] == [f"link_{i}" for i in range(1, 6)]
    assert all(b.along == ("a", "d") and b.radius == 0.1 for b in robot.design.bodies)
    pairs = watched_pairs(robot)
    assert pairs and all(j - i >= 2 for i, j in pairs)  # consecutive bodies are adjacent
    ClearanceModel(robot, None, 0.1)  # the clearance model takes them


def _p01() -> Task:
    task = load_task("tunnel-87")
    return task.subset([i for i, n in enumerate(task.names) if n.startswith("P01/")])


def test_a_run_keeps_the_clearance_and_reports_it() -> None:
    task = _p01()
    item = WorkItem("sb60", 1, 0, 0, load_robot("sb60"), task, clearance=0.1)
    res = run_item(item)
    assert res.error == "" and res.feasible
    assert res.n_points < len(task)  # the poses no design can serve are left out
    assert res.measures is not None and res.measures.clearance >= 0.1 - 1e-12
    plain = run_item(WorkItem("sb60", 1, 0, 0, load_robot("sb60"), task))
    assert plain.measures is not None and math.isnan(plain.measures.clearance)
    assert plain.n_points == len(task)


def test_what_cannot_be_kept_clear_is_rejected() -> None:
    task = _p01()
    # the tunnel is 7.2 m high: no pose keeps the feed 4 m from it, every pose left out
    far = run_item(WorkItem("sb60", 1, 0, 0, load_robot("sb60"), task, clearance=4.0))
    assert not far.feasible and "no pose" in far.error
    # a template without bodies cannot be checked
    bare = run_item(WorkItem("RRPRR", 1, 0, 0, to_template("RRPRR"), task, clearance=0.1))
    assert not bare.feasible and "bodies" in bare.error
    assert np.asarray(bare.q).size == 0
