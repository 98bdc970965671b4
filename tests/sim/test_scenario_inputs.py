"""What a scenario reads from outside: a URDF with a tip, package dirs, required packages,
a scan of its own meshes, automatic self-collision pairs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
import yaml

import reachwise
from reachwise.errors import InputError, MissingDependency
from reachwise.io.urdf import export_urdf
from reachwise.sim.scenarios import load_scenario, scenario_from_dict
from reachwise.sim.world import build_world


def _scenario(tmp_path: Path, robot: object, watch: list[dict], **extra: object) -> Path:
    data = {
        "name": "t",
        "duration": 1.0,
        "robots": [{"name": "arm", "robot": robot, "q0": [0.1] * 6, "goals": []}],
        "watch": watch,
        **extra,
    }
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_a_urdf_with_a_tip_and_auto_self_pairs(tmp_path: Path) -> None:
    puma = reachwise.load_robot("puma560")
    (tmp_path / "robots").mkdir()
    export_urdf(puma, tmp_path / "robots" / "puma.urdf")
    robot = {"file": "robots/puma.urdf", "tip": "link_6"}
    # the exported URDF carries no shapes: the links get clouds from a mesh of ours
    links = {f"link_{i}": {"mesh": "box.stl", "points": 200} for i in range(1, 7)}
    trimesh.creation.box(extents=(0.06, 0.06, 0.25)).export(tmp_path / "box.stl")
    path = _scenario(
        tmp_path,
        robot,
        [{"self": {"robot": "arm", "pairs": "auto", "samples": 300}, "margin": 0.05}],
    )
    data = yaml.safe_load(path.read_text())
    data["robots"][0]["link_clouds"] = links
    data["robots"][0]["links"] = list(links)
    path.write_text(yaml.safe_dump(data))
    sc = load_scenario(path)
    sc.cache_dir = tmp_path / "results"
    world = build_world(sc)
    r = world.robots["arm"]
    np.testing.assert_allclose(r.fk(np.full(6, 0.1)), puma.fk(np.full(6, 0.1)), atol=1e-12)
    assert world.pairs  # some pairs watched, never adjacent ones
    for p in world.pairs:
        a, b = (s.split("/")[1] for s in p.split("|"))
        assert abs(int(a[5:]) - int(b[5:])) > 1
    cached = tmp_path / "results" / "self-pairs-arm.yaml"
    assert cached.is_file() and "excluded" in yaml.safe_load(cached.read_text())


def test_nested_self_and_its_errors() -> None:
    base = {"name": "t", "duration": 1.0, "robots": [{"name": "arm", "robot": "panda",
                                                       "q0": [0.0] * 7}]}  # fmt: skip
    sc = scenario_from_dict({**base, "watch": [{"self": {"robot": "arm", "pairs": "auto"},
                                                "margin": 0.05}]})  # fmt: skip
    w = sc.spec.watch[0]
    assert (w.self_, w.pairs, w.samples) == ("arm", "auto", 10_000)
    with pytest.raises(InputError, match="needs robot"):
        scenario_from_dict({**base, "watch": [{"self": {"pairs": "auto"}, "margin": 0.05}]})
    with pytest.raises(InputError, match="given twice"):
        scenario_from_dict(
            {**base, "watch": [{"self": {"robot": "arm", "margin": 0.1}, "margin": 0.05}]}
        )
    with pytest.raises(InputError, match="pairs"):
        scenario_from_dict({**base, "watch": [{"self": "arm", "pairs": "some", "margin": 0.05}]})


def test_a_missing_package_is_one_clear_line(tmp_path: Path) -> None:
    path = _scenario(tmp_path, "puma560", [], requires={"no-such-distribution-xyz": "robots"})
    with pytest.raises(MissingDependency) as info:
        build_world(path)
    msg = str(info.value)
    assert "\n" not in msg and "no-such-distribution-xyz" in msg
    assert 'pip install "reachwise[robots]"' in msg and "scenario 't'" in msg


def test_a_robot_file_package_uri_that_cannot_be_found_names_the_field(tmp_path: Path) -> None:
    path = _scenario(tmp_path, {"file": "package://no_such_pkg/r.urdf"}, [])
    with pytest.raises(InputError, match=r"robots\.arm\.robot.*unknown package 'no_such_pkg'"):
        build_world(path)


def test_the_scanner_on_a_mesh_of_ours_sees_its_front(tmp_path: Path) -> None:
    box = trimesh.creation.box(extents=(0.2, 0.6, 0.5))
    box.export(tmp_path / "box.obj")
    scan = {
        "meshes": [{"mesh": "box.obj", "pose": {"xyz": [1.5, 0.0, 0.25]}}],
        "floor": 0.0,
        "pose": {"xyz": [0.0, 0.0, 1.0]},
        "azimuth_deg": [-20, 20],
        "tilt_deg": [10, 40],
        "crop": [[1.0, -0.5, 0.02], [2.0, 0.5, 1.0]],
        "voxel": 0.02,
    }
    path = _scenario(tmp_path, "puma560", [], objects=[{"name": "scan", "scanner": scan}])
    cloud = build_world(path).scene.objects["scan"].cloud.points
    assert len(cloud) > 100
    x = cloud - (1.5, 0.0, 0.25)
    gap = np.max(np.abs(x) - (0.1, 0.3, 0.25), axis=1)  # box distance where outside
    assert np.all(gap <= 0.02 + 1e-9)  # every point on the box (within a voxel)
    assert not np.any((x[:, 0] > 0.09) & (x[:, 2] < 0.22))  # its far face is not seen
    bad = dict(scan, crop=[[2.0, 0, 0], [1.0, 1, 1]])
    with pytest.raises(InputError, match="crop"):
        load_scenario(_scenario(tmp_path, "puma560", [], objects=[{"name": "s", "scanner": bad}]))
