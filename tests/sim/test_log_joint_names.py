"""A run's CSV log names each joint column after the robot's joint (its URDF's or robot
file's name), the npz keeps the names, and a log read back has them."""

from __future__ import annotations

import csv
from pathlib import Path

import reachwise
from reachwise.sim.log import load_log


def test_the_csv_log_names_the_joints(tmp_path: Path) -> None:
    log = reachwise.simulate("p3-self-collision", duration=0.05)
    robot = reachwise.load_robot("sb60")
    names = tuple(j.name for j in robot.joints if j.movable)
    assert len(names) == robot.n and all(names)
    assert log.joint_names == {"boom": names}
    log.save(tmp_path)
    with (tmp_path / "log.csv").open(newline="") as fh:
        head = next(csv.reader(fh))
    assert head[1 : 1 + robot.n] == [f"boom.{n}" for n in names]
    assert not [c for c in head if c.startswith("boom.q")]
    assert load_log(tmp_path).joint_names == {"boom": names}


def test_a_log_without_names_keeps_numbered_columns(tmp_path: Path) -> None:
    log = reachwise.simulate("p3-self-collision", duration=0.05)
    bare = type(log)(**{**log.__dict__, "joint_names": {}})
    assert bare.joint_columns("boom") == [f"boom.q{k + 1}" for k in range(log.q["boom"].shape[1])]
