"""``reachwise cloud info|sample|downsample|crop`` and ``reachwise scan`` end to end."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh
from typer.testing import CliRunner

from reachwise.cli import app, main
from reachwise.errors import CloudError, InputError, ReachwiseError
from reachwise.geometry.cloud import PointCloud
from reachwise.io.clouds import load_cloud, save_cloud

runner = CliRunner()


@pytest.fixture
def cloud_file(tmp_path: Path) -> Path:
    rng = np.random.default_rng(0)
    path = tmp_path / "in.ply"
    save_cloud(PointCloud(rng.uniform(-1, 1, (2000, 3))), path)
    return path


def test_info_text_and_json(cloud_file: Path) -> None:
    res = runner.invoke(app, ["cloud", "info", str(cloud_file)])
    assert res.exit_code == 0, res.output
    assert "2000 points" in res.output and "nearest-neighbour spacing" in res.output
    res = runner.invoke(app, ["cloud", "info", str(cloud_file), "--json"])
    assert res.exit_code == 0, res.output
    info = json.loads(res.output)
    pts = load_cloud(cloud_file).points
    assert info["points"] == 2000 and info["format"] == "ply"
    np.testing.assert_allclose(info["min"], pts.min(axis=0), rtol=0, atol=0)
    np.testing.assert_allclose(info["centroid"], pts.mean(axis=0), rtol=1e-12)
    assert 0 < info["spacing"]["min"] <= info["spacing"]["median"] <= info["spacing"]["max"]


def test_info_single_point(tmp_path: Path) -> None:
    path = tmp_path / "one.xyz"
    path.write_text("1 2 3\n")
    res = runner.invoke(app, ["cloud", "info", str(path), "--json"])
    assert res.exit_code == 0 and json.loads(res.output)["spacing"] is None


def test_sample_mesh(tmp_path: Path) -> None:
    mesh = tmp_path / "part.stl"
    trimesh.creation.box(extents=(1.0, 2.0, 3.0)).export(mesh)
    out = tmp_path / "part.pcd"
    args = ["cloud", "sample", str(mesh), "--points", "500", "--seed", "3", "--out", str(out)]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    pts = load_cloud(out).points
    assert pts.shape == (500, 3)
    assert np.all(np.abs(pts) <= np.array([0.5, 1.0, 1.5]) + 1e-6)
    out2 = tmp_path / "again.pcd"
    assert runner.invoke(app, [*args[:-1], str(out2)]).exit_code == 0
    np.testing.assert_array_equal(load_cloud(out2).points, pts)


def test_downsample_and_crop(cloud_file: Path, tmp_path: Path) -> None:
    thin = tmp_path / "thin.npy"
    res = runner.invoke(
        app, ["cloud", "downsample", str(cloud_file), "--voxel", "0.5", "--out", str(thin)]
    )
    assert res.exit_code == 0, res.output
    src = load_cloud(cloud_file).points
    assert len(np.load(thin)) == len(np.unique(np.floor(src / 0.5), axis=0))
    box = tmp_path / "box.csv"
    res = runner.invoke(
        app,
        [
            "cloud",
            "crop",
            str(cloud_file),
            *"--min -0.5 -1 0 --max 0.5 1 1 --out".split(),
            str(box),
        ],
    )
    assert res.exit_code == 0, res.output
    inside = np.all((src >= [-0.5, -1, 0]) & (src <= [0.5, 1, 1]), axis=1)
    np.testing.assert_array_equal(load_cloud(box).points, src[inside])


def test_scan_writes_the_p5_cloud(tmp_path: Path) -> None:
    out = tmp_path / "scan.ply"
    res = runner.invoke(app, ["scan", "p5-floor-obstacle", "--out", str(out), "--json"])
    assert res.exit_code == 0, res.output
    summary = json.loads(res.output)
    cloud = load_cloud(out)
    assert summary["points"] == len(cloud) and 5000 <= len(cloud) <= 6000
    assert summary["returns"] > len(cloud)
    raw = tmp_path / "raw.npy"
    opts = "--raw --coarsen 3 --noise 0.01 --seed 4".split()
    res = runner.invoke(app, ["scan", "p5-floor-obstacle", "--out", str(raw), *opts])
    assert res.exit_code == 0, res.output
    assert "returns" in res.output
    assert len(np.load(raw)) > 5000


@pytest.mark.parametrize(
    ("args", "error", "match"),
    [
        (["cloud", "info", "{tmp}/missing.ply"], CloudError, "no such file"),
        (
            ["cloud", "downsample", "{in}", "--voxel", "0", "--out", "{tmp}/o.ply"],
            CloudError,
            "voxel",
        ),
        (
            "cloud crop {in} --min 5 5 5 --max 6 6 6 --out {tmp}/o.ply".split(),
            CloudError,
            "no point of 2000",
        ),
        (["cloud", "info", "{tmp}/x.las"], CloudError, "unknown cloud format"),
        (["scan", "nowhere", "--out", "{tmp}/o.ply"], InputError, "unknown scene"),
        (
            ["scan", "p5-floor-obstacle", "--out", "{tmp}/o.ply", "--noise", "-1"],
            InputError,
            "noise",
        ),
        (["cloud", "sample", "{tmp}/m.stl", "--out", "{tmp}/o.ply"], CloudError, "no such file"),
    ],
)
def test_errors_are_reachwise_errors(
    cloud_file: Path, tmp_path: Path, args: list[str], error: type, match: str
) -> None:
    argv = [a.replace("{tmp}", str(tmp_path)).replace("{in}", str(cloud_file)) for a in args]
    res = runner.invoke(app, argv)
    assert isinstance(res.exception, error), res.output
    assert match in str(res.exception)
    assert not (tmp_path / "o.ply").exists()


def test_main_prints_one_line_and_exits_2(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "cut.ply"
    bad.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 10\n")
    monkeypatch.setattr(sys, "argv", ["reachwise", "cloud", "info", str(bad)])
    with pytest.raises(SystemExit) as exc:
        main()
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and "cut.ply: header: not a valid PLY file" in err
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert issubclass(CloudError, ReachwiseError)


def test_max_points_bounds_the_cloud_read(tmp_path: Path) -> None:
    path = tmp_path / "c.xyz"
    np.savetxt(path, np.random.default_rng(0).uniform(size=(20, 3)))
    res = CliRunner().invoke(app, ["cloud", "info", str(path), "--max-points", "19"])
    assert res.exit_code != 0
    assert isinstance(res.exception, CloudError) and "more than the bound 19" in str(res.exception)
    assert str(path) in str(res.exception)
    ok = CliRunner().invoke(app, ["cloud", "info", str(path), "--max-points", "20", "--json"])
    assert ok.exit_code == 0, ok.output
