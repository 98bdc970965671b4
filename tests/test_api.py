"""``reachwise.synthesize``: the facade resolves names and files, then calls the math layer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import reachwise
from reachwise.errors import InputError
from reachwise.io.robot_file import save_robot
from reachwise.io.task_file import save_task
from reachwise.synthesis.synthesize import synthesize as synthesize_objects


def test_names_files_and_objects_give_the_same_design(tmp_path: Path) -> None:
    task = reachwise.load_task("tunnel-87").subset(np.arange(0, 87, 29), name="tunnel-87")
    robot = reachwise.load_robot("sb60")
    save_task(task, tmp_path / "task.yaml")
    save_robot(robot, tmp_path / "boom.yaml")
    ref = synthesize_objects(task, robot, runs=1, seed=2)
    by_file = reachwise.synthesize(
        tmp_path / "task.yaml", str(tmp_path / "boom.yaml"), runs=1, seed=2
    )
    by_name = reachwise.synthesize(task, "sb60", runs=1, seed=2)
    # a name resolves to the very same objects; a file round trip of the task may move
    # its poses by a rounding error (quaternions), so the solution agrees to that level
    assert np.array_equal(by_name.best.design, ref.best.design)
    assert np.array_equal(by_name.q, ref.q)
    assert by_file.reached.all() == ref.reached.all()
    assert np.allclose(by_file.best.design, ref.best.design, atol=1e-6)
    assert np.allclose(by_file.q, ref.q, atol=1e-6)


def test_unknown_names_are_input_errors() -> None:
    task = reachwise.load_task("tunnel-87")
    with pytest.raises(InputError, match="no-such-robot"):
        reachwise.synthesize(task, "no-such-robot", runs=1)
    with pytest.raises(InputError, match="no-such-task"):
        reachwise.synthesize("no-such-task", "sb60", runs=1)


def test_objective_by_argument_or_from_the_design_section() -> None:
    from dataclasses import replace

    task = reachwise.load_task("tunnel-87").subset(np.arange(0, 87, 29), name="tunnel-87")
    robot = reachwise.load_robot("sb60")
    asked = reachwise.synthesize(task, robot, runs=1, seed=2, objective={"size": 1.0})
    assert asked.objective == {"size": 1.0} and asked.best.improved
    assert asked.best.objective_final["size"] <= asked.best.objective_start["size"]
    filed = replace(robot, design=replace(robot.design, objective={"size": 1.0}))
    by_file = reachwise.synthesize(task, filed, runs=1, seed=2)
    assert by_file.objective == {"size": 1.0}
    assert np.array_equal(by_file.best.design, asked.best.design)
    none = reachwise.synthesize(task, filed, runs=1, seed=2, objective={})
    assert none.objective == {} and not none.best.improved
