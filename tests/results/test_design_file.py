"""design.yaml places every body: another forward kinematics, written here from the DH
table of the reloaded file, places the listed parts, and brute-force distances between
them (and from the tunnel) equal the clearance the synthesis reports per pose."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from reachwise import load_robot, load_task, synthesize
from reachwise.errors import RobotFileError
from reachwise.kinematics.robot import Robot
from reachwise.results.synthesis_out import load_synthesis, write_synthesis
from reachwise.tasks.workspace import TunnelEnvelope

CLEARANCE = 0.1


def _rot_x(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def _rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _trans(x: float, y: float, z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def frames(robot: Robot, q: np.ndarray) -> dict[str, np.ndarray]:
    """Modified DH (P-I Eq. 2–3), written out: ``T_{j+1} = T_j Rx(α) Tx(a) Rz(θ) Tz(d)``
    with the joint value added to ``θ`` (revolute) or ``d`` (prismatic); ``link_j`` is
    frame ``j``, ``tool`` the last frame times the tool transform."""
    assert robot.convention == "modified"
    T = np.array(robot.base, dtype=float)
    out = {"link_0": T}
    i = 0
    for j, joint in enumerate(robot.joints):
        theta, d = joint.theta, joint.d
        if joint.type == "revolute":
            theta += q[i]
            i += 1
        elif joint.type == "prismatic":
            d += q[i]
            i += 1
        T = T @ _rot_x(joint.alpha) @ _trans(joint.a, 0, 0) @ _rot_z(theta) @ _trans(0, 0, d)
        out[f"link_{j + 1}"] = T
    out["tool"] = T @ np.array(robot.tool, dtype=float)
    return out


def _place(F: dict[str, np.ndarray], point: dict) -> np.ndarray:
    T = F[point["link"]]
    return T[:3, :3] @ np.array(point["xyz"], dtype=float) + T[:3, 3]


def _samples(a: np.ndarray, b: np.ndarray, step: float = 0.005) -> np.ndarray:
    n = max(2, int(np.ceil(np.linalg.norm(b - a) / step)) + 1)
    return a[None] + np.linspace(0.0, 1.0, n)[:, None] * (b - a)[None]


def brute_force(placed: dict, F: dict[str, np.ndarray], envelope: TunnelEnvelope) -> float:
    """The smallest clearance at one pose: every watched pair's parts (sampled axes,
    minus both radii) and every part against the tunnel (its axis outside the contact
    zone, minus the radius)."""
    parts = placed["parts"]
    axes: dict[str, list[tuple[np.ndarray, float, float]]] = {}
    for p in parts.values():
        c = p["capsule"]  # the sb60 stand-in bodies are capsules
        a, b = _place(F, c["start"]), _place(F, c["end"])
        axes.setdefault(p["body"], []).append((_samples(a, b), c["radius"], c.get("contact", 0)))
    best = np.inf
    for x, y in placed["watched"]:
        for sa, ra, _ in axes[x]:
            for sb, rb, _ in axes[y]:
                d = np.sqrt(((sa[:, None] - sb[None]) ** 2).sum(-1)).min() - ra - rb
                best = min(best, d)
    for body in axes.values():
        for s, r, contact in body:
            if contact:
                length = np.linalg.norm(s[-1] - s[0])
                s = _samples(s[0], s[0] + (s[-1] - s[0]) * (1 - contact / length))
            best = min(best, float(envelope.signed_distance(s).min()) - r)
    return float(best)


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, object]:
    task = load_task("tunnel-87")
    keep = [i for i, n in enumerate(task.names) if n.split("/")[0] in ("P01", "P02")]
    res = synthesize(task.subset(keep), "sb60", runs=1, seed=0, clearance=CLEARANCE)
    assert res.reached.all()
    return write_synthesis(res, tmp_path_factory.mktemp("design")), res


def test_placed_bodies_reproduce_the_reported_clearance(written: tuple[Path, object]) -> None:
    folder, _ = written
    data = yaml.safe_load((folder / "design.yaml").read_text())
    placed = data["placed_bodies"]
    assert placed["clearance"] == CLEARANCE
    assert {p["body"] for p in placed["parts"].values()} == {
        "boom_root", "boom", "feed_swing_bracket", "rollover_arm", "feed",
    }  # fmt: skip
    assert {"boom.a", "boom.d"} <= set(placed["parts"])  # two segments, two parts
    out = load_synthesis(folder)
    robot = load_robot(folder / "design.yaml")  # the file still loads as a robot
    task = out.task
    assert task is not None and task.envelope is not None
    reported = np.array(
        [float(r) for r in _column(folder / "points.csv", "clearance_m")], dtype=float
    )
    for k in range(len(out.names)):
        F = frames(robot, out.q[k])
        # this forward kinematics reaches the task pose: it is the design's
        assert np.linalg.norm(F["tool"][:3, 3] - task.positions[k]) <= task.tol_position[k]
        d = brute_force(placed, F, task.envelope)
        assert d >= CLEARANCE - 1e-9
        # sampling 5 mm apart only overestimates a distance, by under 1 mm here
        assert reported[k] <= d + 1e-9
        assert reported[k] == pytest.approx(d, abs=2e-3)


def test_a_checker_that_drops_a_part_sees_a_different_clearance(
    written: tuple[Path, object],
) -> None:
    """The comparison above can fail: without the feed's part the brute-force clearance
    is not the reported one at some pose."""
    folder, _ = written
    data = yaml.safe_load((folder / "design.yaml").read_text())
    placed = data["placed_bodies"]
    cut = {**placed, "parts": {k: v for k, v in placed["parts"].items() if k != "feed"}}
    cut["watched"] = [w for w in placed["watched"] if "feed" not in w]
    out = load_synthesis(folder)
    robot = load_robot(folder / "design.yaml")
    assert out.task is not None and out.task.envelope is not None
    reported = np.array([float(r) for r in _column(folder / "points.csv", "clearance_m")])
    diffs = [
        abs(brute_force(cut, frames(robot, out.q[k]), out.task.envelope) - reported[k])
        for k in range(len(out.names))
    ]
    assert max(diffs) > 2e-3


def test_a_malformed_placed_section_is_a_file_error(
    written: tuple[Path, object], tmp_path: Path
) -> None:
    folder, _ = written
    data = yaml.safe_load((folder / "design.yaml").read_text())
    part = next(iter(data["placed_bodies"]["parts"].values()))
    part["capsule"]["radius"] = -1.0
    bad = tmp_path / "design.yaml"
    bad.write_text(yaml.safe_dump(data))
    with pytest.raises(RobotFileError, match="placed_bodies"):
        load_robot(bad)


def _column(path: Path, name: str) -> list[str]:
    import csv

    with path.open(newline="") as fh:
        return [row[name] for row in csv.DictReader(fh)]
