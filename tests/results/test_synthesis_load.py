"""``load_synthesis`` reads back what ``write_synthesis`` wrote (round trip)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from reachwise import load_task, synthesize
from reachwise.errors import InputError
from reachwise.io.ros.joint_state import robot_joint_names
from reachwise.io.task_file import save_task
from reachwise.results.synthesis_out import load_synthesis, write_synthesis


@pytest.fixture(scope="module")
def result():  # type: ignore[no-untyped-def]
    task = load_task("tunnel-87").subset(np.arange(3, 87, 11), name="tunnel-87")
    return synthesize(task, "sb60", runs=1, seed=0)


def test_round_trip(tmp_path: Path, result) -> None:  # type: ignore[no-untyped-def]
    out = load_synthesis(write_synthesis(result, tmp_path / "s"))
    best = result.best
    np.testing.assert_array_equal(out.q, best.q)
    assert out.status == best.status
    np.testing.assert_array_equal(out.reached, result.reached)
    task = result.problem.task
    np.testing.assert_array_equal(out.positions, task.positions)
    np.testing.assert_array_equal(out.dims, task.dims)
    assert out.names == task.names and out.groups == task.groups
    np.testing.assert_array_equal(out.position_error, best.position_error)
    np.testing.assert_array_equal(out.orientation_error, best.orientation_error)
    np.testing.assert_array_equal(out.lci_final, best.lci_final)
    # the design reads back as the same kinematics
    np.testing.assert_allclose(out.robot.fk_all(best.q), best.robot.fk_all(best.q), atol=1e-9)
    # the task is found again: named built-in, matched point by point
    assert out.task is not None
    np.testing.assert_allclose(out.task.poses, task.poses, atol=1e-9)
    np.testing.assert_allclose(out.target_axes, task.axes, atol=1e-9)


def test_task_yaml_wins_and_unknown_tasks_fall_back_to_the_design_axes(
    tmp_path: Path,
    result,  # type: ignore[no-untyped-def]
) -> None:
    folder = write_synthesis(result, tmp_path / "s")
    (folder / "summary.json").write_text(
        (folder / "summary.json").read_text().replace('"tunnel-87"', '"my-task"')
    )
    out = load_synthesis(folder)
    assert out.task is None
    np.testing.assert_allclose(out.target_axes, out.robot.fk(out.q)[:, :3, 2])
    save_task(result.problem.task, folder / "task.yaml")
    out = load_synthesis(folder)
    assert out.task is not None and len(out.task) == len(out.q)


def test_missing_parts_name_file_and_field(tmp_path: Path, result) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(InputError, match=r"design\.yaml"):
        load_synthesis(tmp_path)
    folder = write_synthesis(result, tmp_path / "s")
    lines = (folder / "points.csv").read_text().splitlines()
    (folder / "points.csv").write_text("\n".join([lines[0], lines[1].replace("full", "maybe")]))
    with pytest.raises(InputError, match=r"points\[0\]\.status"):
        load_synthesis(folder)
    (folder / "points.csv").write_text(
        lines[0].replace(",feed_extension", "") + "\n" + lines[1] + "\n"
    )
    with pytest.raises(InputError, match="feed_extension"):
        load_synthesis(folder)


def test_joint_columns_are_the_robots_joint_names_and_numbered_ones_still_read(
    tmp_path: Path,
    result,  # type: ignore[no-untyped-def]
) -> None:
    """``points.csv`` names each joint column after the design's joint (sb60's
    ``boom_swing`` … ``feed_extension``), in ``q`` order; a file written with the
    numbered columns ``q0`` … of earlier versions reads back the same joint vectors."""
    folder = write_synthesis(result, tmp_path / "s")
    with (folder / "points.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    names = robot_joint_names(result.best.robot)
    assert names[0] == "boom_swing" and names[-1] == "feed_extension"
    got = np.array([[float(r[n]) for n in names] for r in rows])
    np.testing.assert_array_equal(got, result.best.q)
    text = (folder / "points.csv").read_text()
    head, rest = text.split("\n", 1)
    for i, n in enumerate(names):
        head = head.replace(f",{n}", f",q{i}")
    (folder / "points.csv").write_text(head + "\n" + rest)
    np.testing.assert_array_equal(load_synthesis(folder).q, result.best.q)
