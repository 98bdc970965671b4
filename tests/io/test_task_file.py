"""Task files (YAML, JSON, CSV): round trips, the built-in tunnel-87, and a clear error
(file, field, reason) for every kind of mistake."""

from __future__ import annotations

import json
import math
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from reachwise.errors import TaskError, UnknownName
from reachwise.io.task_file import (
    builtin_task_text,
    builtin_tasks,
    load_task,
    render_task,
    save_task,
    task_from_dict,
)
from reachwise.tasks import Task, TaskPoint, TunnelEnvelope, TunnelProfile, tunnel_87

DESIGN_EXAMPLE = """\
name: tunnel-87
tolerance: {position: 0.001, orientation: 0.001}     # m, rad; per point override allowed
points:
  - {xyz: [6.0, 0.5, 1.8], quat: [0, 0.7071, 0, 0.7071]}   # 6-D, quaternion (x, y, z, w)
  - {xyz: [6.0, 1.0, 2.4], axis: [1, 0, 0], dims: 5}        # 5-D: position + tool z-axis
  - {xyz: [6.0, 1.5, 3.0], dims: 3}                         # position only
"""


def write(tmp_path: Path, text: str, name: str = "task.yaml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def write_yaml(tmp_path: Path, data: object, name: str = "task.yaml") -> Path:
    return write(tmp_path, yaml.safe_dump(data, sort_keys=False), name)


def mixed_task(envelope: bool = True) -> Task:
    rng = np.random.default_rng(7)
    pts = []
    for i in range(12):
        pos = rng.uniform(-5, 5, 3)
        kind = i % 4
        if kind == 0:
            pts.append(TaskPoint(pos, rotation=Rotation.random(random_state=i).as_matrix()))
        elif kind == 1:
            pts.append(TaskPoint(pos, axis=rng.normal(size=3), name=f"h{i}", group="cut"))
        elif kind == 2:
            pts.append(TaskPoint(pos, tol_position=0.01, tol_orientation=0.02, group="a, b"))
        else:
            R = Rotation.random(random_state=i).as_matrix()
            pts.append(TaskPoint(pos, rotation=R, dims=5, name="five with rotation"))
    env = TunnelEnvelope(TunnelProfile(6.0, 5.5, 1.8, 0.2, -1.0), (-10.0, math.inf), 7.0)
    return Task("mixed", tuple(pts), env if envelope else None)


def assert_same(a: Task, b: Task, envelope: bool = True) -> None:
    assert a.name == b.name and len(a) == len(b)
    assert np.allclose(a.poses, b.poses, atol=1e-12)
    assert np.array_equal(a.dims, b.dims)
    assert np.array_equal(a.tol_position, b.tol_position)
    assert np.array_equal(a.tol_orientation, b.tol_orientation)
    assert a.names == b.names and a.groups == b.groups
    assert [p.rotation is None for p in a] == [p.rotation is None for p in b]
    if envelope:
        assert a.envelope == b.envelope


@pytest.mark.parametrize("suffix", [".yaml", ".yml", ".json", ".csv"])
def test_round_trip(tmp_path: Path, suffix: str) -> None:
    with_env = suffix != ".csv"
    task = mixed_task(envelope=with_env)
    path = tmp_path / f"mixed{suffix}"
    save_task(task, path)
    back = load_task(path)
    assert_same(task, back, with_env)
    # and once more, rounded: then the text is a fixed point
    path2, path3 = tmp_path / f"r2{suffix}", tmp_path / f"r3{suffix}"
    save_task(back, path2, decimals=9)
    save_task(load_task(path2), path3, decimals=9)
    assert path3.read_text() == path2.read_text()


def test_design_md_example_loads(tmp_path: Path) -> None:
    t = load_task(write(tmp_path, DESIGN_EXAMPLE))
    assert t.name == "tunnel-87" and t.dims.tolist() == [6, 5, 3]
    assert np.allclose(t[0].axis, [1, 0, 0], atol=1e-4)  # Ry(90°): the tool z points ahead
    assert np.allclose(t.tol_position, 1e-3) and t.envelope is None


def test_orientation_forms_agree(tmp_path: Path) -> None:
    rpy = [0.1, -0.4, 2.0]
    R = Rotation.from_euler("xyz", rpy).as_matrix()  # URDF: Rz(yaw) Ry(pitch) Rx(roll)
    q = Rotation.from_matrix(R).as_quat()
    data = {
        "name": "forms",
        "points": [
            {"xyz": [0, 0, 0], "rpy": rpy},
            {"xyz": [0, 0, 0], "rpy_deg": np.degrees(rpy).tolist()},
            {"xyz": [0, 0, 0], "quat": q.tolist()},
            {"xyz": [0, 0, 0], "quat": (q * (1 + 5e-4)).tolist()},  # normalized
            {"xyz": [0, 0, 0], "axis": (3 * R[:, 2]).tolist()},
        ],
    }
    t = load_task(write_yaml(tmp_path, data))
    for i in range(4):
        assert np.allclose(t[i].rotation, R, atol=1e-12)
    assert np.allclose(t[4].axis, R[:, 2]) and t.dims.tolist() == [6, 6, 6, 6, 5]


def test_tolerances_default_and_override(tmp_path: Path) -> None:
    data = {
        "tolerance": {"position": 0.005},
        "points": [
            {"xyz": [0, 0, 0]},
            {"xyz": [0, 0, 0], "tolerance": {"orientation": 0.01}},
            {"xyz": [0, 0, 0], "tolerance": {"position": 0.02, "orientation": 0.03}},
        ],
    }
    t = load_task(write_yaml(tmp_path, data, "tols.yaml"))
    assert t.name == "tols"  # default name: the file stem
    assert t.tol_position.tolist() == [0.005, 0.005, 0.02]
    assert t.tol_orientation.tolist() == [1e-3, 0.01, 0.03]


BAD = [
    ({"points": []}, "points", "empty task"),
    ({"name": "x"}, "points", "Field required"),
    ({"points": [{"xyz": [1, float("nan"), 0]}]}, "points[0].xyz[1]", "finite"),
    ({"points": [{"xyz": [0, 0, 0]}, {"xyz": [0, 0, 0], "quat": [0, 0, float("inf"), 1]}]},
     "points[1].quat[2]", "finite"),
    ({"points": [{"xyz": [0, 0, 0], "axis": [0, 0, 0]}]}, "points[0].axis", "zero-length"),
    ({"points": [{"xyz": [6, 1]}]}, "points[0].xyz", "expected 3 values"),
    ({"points": [{"xyz": [0, 0, 0], "quat": [0, 0.7, 0, 0.7]}]}, "points[0].quat", "unit norm"),
    ({"points": [{"xyz": [0, 0, 0], "quat": [0, 0, 0]}]}, "points[0].quat", "expected 4 values"),
    ({"tolerance": {"position": 0}, "points": [{"xyz": [0, 0, 0]}]}, "tolerance.position",
     "greater than 0"),
    ({"points": [{"xyz": [0, 0, 0], "tolerance": {"orientation": -1}}]},
     "points[0].tolerance.orientation", "greater than 0"),
    ({"points": [{"xyz": [0, 0, 0], "dims": 6}]}, "points[0].dims", "needs an orientation"),
    ({"points": [{"xyz": [0, 0, 0], "dims": 6, "axis": [1, 0, 0]}]}, "points[0].dims",
     "needs an orientation"),
    ({"points": [{"xyz": [0, 0, 0], "dims": 5}]}, "points[0].dims", "needs an axis"),
    ({"points": [{"xyz": [0, 0, 0], "dims": 4}]}, "points[0].dims", "3, 5 or 6"),
    ({"points": [{"xyz": [0, 0, 0], "colour": "red"}]}, "points[0].colour", "Extra inputs"),
    ({"pionts": [{"xyz": [0, 0, 0]}]}, "pionts", "Extra inputs"),
    ({"points": [{"xyz": [0, 0, 0], "quat": [0, 0, 0, 1], "rpy": [0, 0, 0]}]},
     "points[0].rpy", "not both"),
    ({"points": [{"xyz": [0, 0, 0]}], "envelope": {"tunnel": {"width": 4, "height": 5,
      "arch_height": 3}}}, "envelope.tunnel.arch_height", "half the width"),
    ({"points": [{"xyz": [0, 0, 0]}], "envelope": {"tunnel": {"width": 4, "height": 5},
      "x_range": [5, 1]}}, "envelope.x_range", "x_min < x_max"),
]  # fmt: skip


@pytest.mark.parametrize(("data", "field", "reason"), BAD)
@pytest.mark.parametrize("suffix", [".yaml", ".json"])
def test_bad_files_name_file_field_and_reason(
    tmp_path: Path, data: dict, field: str, reason: str, suffix: str
) -> None:
    text = json.dumps(data) if suffix == ".json" else yaml.safe_dump(data)
    path = write(tmp_path, text, f"bad{suffix}")
    with pytest.raises(TaskError, match=reason) as info:
        load_task(path)
    assert info.value.source == str(path)
    assert info.value.field == field
    assert str(path) in str(info.value) and field in str(info.value)


def test_not_a_mapping_bad_syntax_missing_file_and_unknown_type(tmp_path: Path) -> None:
    with pytest.raises(TaskError, match="mapping"):
        load_task(write(tmp_path, "- 1\n- 2\n"))
    with pytest.raises(TaskError, match="not valid YAML"):
        load_task(write(tmp_path, "points: [\n"))
    with pytest.raises(TaskError, match="not valid JSON"):
        load_task(write(tmp_path, "{points:", "t.json"))
    with pytest.raises(TaskError, match="no such file"):
        load_task(tmp_path / "missing.yaml")
    with pytest.raises(TaskError, match="unknown task file type"):
        load_task(write(tmp_path, "x", "t.txt"))
    with pytest.raises(UnknownName, match="unknown built-in task 'tunnel-88'; valid: tunnel-87"):
        load_task("tunnel-88")


CSV_GOOD = """\
# drill plan exported from a spreadsheet
# name: from-csv
x,y,z,qx,qy,qz,qw,ax,ay,az,roll_deg,pitch_deg,yaw_deg,dims,tol_position,name,group
6.0,0.5,1.8,0,0.7071068,0,0.7071068,,,,,,,,,a,cut
6.0,1.0,2.4,,,,,1,0,0,,,,5,0.002,"b, c",contour
6.0,1.5,3.0,,,,,,,,0,90,0,,,,

6.0,2.0,3.0,,,,,,,,,,,,,d,
"""


def test_csv_with_every_kind_of_row(tmp_path: Path) -> None:
    t = load_task(write(tmp_path, CSV_GOOD, "plan.csv"))
    assert t.name == "from-csv" and t.dims.tolist() == [6, 5, 6, 3]
    assert np.allclose(t[0].rotation, t[2].rotation, atol=1e-6)
    assert t.names == ("a", "b, c", "", "d") and t.groups == ("cut", "contour", "", "")
    assert t.tol_position.tolist() == [1e-3, 2e-3, 1e-3, 1e-3]
    rad = load_task(
        write(tmp_path, "x,y,z,roll,pitch,yaw\n1,2,3,0,1.5707963267948966,0\n", "r.csv")
    )
    assert np.allclose(rad[0].rotation, t[2].rotation, atol=1e-12)
    minimal = load_task(write(tmp_path, "x,y,z\n1,2,3\n4,5,6\n", "xyz.csv"))
    assert minimal.name == "xyz" and minimal.dims.tolist() == [3, 3]


CSV_BAD = [
    ("x,y,z,w\n1,2,3,4\n", "header", "unknown column 'w'"),
    ("x,y\n1,2\n", "header", "missing z"),
    ("x,y,z,qx,qy,qz\n1,2,3,0,0,0\n", "header", "missing qw"),
    ("x,y,z,x\n1,2,3,4\n", "header", "duplicate column"),
    ("", "header", "no CSV header"),
    ("x,y,z\n", "points", "empty task"),
    ("x,y,z\n1,2,3\n1,2\n", "line 3", "expected 3 cells"),
    ("x,y,z\n1,2,3\n1,nan,3\n", "points[1].xyz[1]", "finite"),
    ("x,y,z\n1,2,3\n1,,3\n", "points[1].xyz", "give all of x, y, z"),
    ("x,y,z,ax,ay,az\n1,2,3,1,,0\n", "points[0].axis", "give all of ax, ay, az"),
    ("x,y,z,ax,ay,az\n1,2,3,0,0,0\n", "points[0].axis", "zero-length"),
    ("x,y,z,qx,qy,qz,qw\n1,2,3,0,0,0,2\n", "points[0].quat", "unit norm"),
    ("x,y,z,dims\n1,2,3,6\n", "points[0].dims", "needs an orientation"),
    ("x,y,z,tol_position\n1,2,3,0\n", "points[0].tolerance.position", "greater than 0"),
    ("x,y,z,qx,qy,qz,qw,ax,ay,az\n1,2,3,0,0,0,1,1,0,0\n", "points[0].axis", "not both"),
]


@pytest.mark.parametrize(("text", "field", "reason"), CSV_BAD)
def test_bad_csv(tmp_path: Path, text: str, field: str, reason: str) -> None:
    path = write(tmp_path, text, "bad.csv")
    with pytest.raises(TaskError, match=reason) as info:
        load_task(path)
    assert info.value.source == str(path) and info.value.field == field
    if field.startswith("points["):
        assert "CSV line" in info.value.reason


def test_builtin_tunnel_87() -> None:
    assert "tunnel-87" in builtin_tasks()
    t = load_task("tunnel-87")
    assert len(t) == 87 and t.name == "tunnel-87" and (t.dims == 6).all()
    ref = tunnel_87()
    assert np.allclose(t.poses, ref.poses, atol=1e-8)
    assert t.names == ref.names and t.groups == ref.groups
    assert t.envelope == ref.envelope


def test_regenerating_tunnel_87_gives_the_shipped_file() -> None:
    shipped = (resources.files("reachwise.data") / "tasks" / "tunnel-87.yaml").read_text()
    assert builtin_task_text("tunnel-87") == shipped


def test_rendered_json_and_rounding() -> None:
    data = json.loads(render_task(mixed_task(), "json"))
    assert data["name"] == "mixed" and len(data["points"]) == 12
    assert data["envelope"]["x_range"] == [-10.0, None] and data["envelope"]["face_x"] == 7.0
    rounded = yaml.safe_load(render_task(mixed_task(), "yaml", decimals=3))
    assert all(round(v, 3) == v for p in rounded["points"] for v in p["xyz"])
    back = task_from_dict(rounded, "rounded")
    assert np.allclose(back.positions, mixed_task().positions, atol=5e-4)
