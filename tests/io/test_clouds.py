"""Cloud files: exact round trips, files written by other tools, and every way to break one."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import plyfile
import pypcd4
import pytest
import trimesh

from reachwise.errors import CloudError
from reachwise.geometry.cloud import PointCloud
from reachwise.io.clouds import CLOUD_FORMATS, cloud_format, load_cloud, load_mesh_cloud, save_cloud

SUFFIXES = sorted(CLOUD_FORMATS)


@pytest.fixture
def cloud() -> PointCloud:
    rng = np.random.default_rng(42)
    pts = rng.normal(size=(257, 3)) * np.array([1e-3, 1.0, 1e4])
    pts[0] = [0.1, -0.0, 1 / 3]
    pts[1] = [np.pi, 1e-300, -2.5e12]
    return PointCloud(pts, name="c")


# ----------------------------------------------------------------------- round trips


@pytest.mark.parametrize("suffix", SUFFIXES)
@pytest.mark.parametrize("ascii", [False, True])
def test_round_trip(tmp_path: Path, cloud: PointCloud, suffix: str, ascii: bool) -> None:
    path = tmp_path / f"cloud{suffix}"
    assert save_cloud(cloud, path, ascii=ascii) == path
    back = load_cloud(path)
    assert back.name == str(path) and back.frame == "world"
    if suffix == ".pcd" and ascii:
        # pypcd4 writes ASCII PCD with "%.10f": 5e-11 m absolute at most
        np.testing.assert_allclose(back.points, cloud.points, rtol=0, atol=5.1e-11)
    else:
        np.testing.assert_array_equal(back.points, cloud.points)
        assert back.points.dtype == np.float64
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temp file left


def test_format_override_and_names(tmp_path: Path, cloud: PointCloud) -> None:
    path = tmp_path / "scan.dat"
    save_cloud(cloud, path, fmt="ply")
    back = load_cloud(path, fmt=".ply", frame="sensor", name="scan")
    assert back.frame == "sensor" and back.name == "scan"
    np.testing.assert_array_equal(back.points, cloud.points)
    assert cloud_format("a.TXT") == "xyz"
    with pytest.raises(CloudError, match=r"scan\.dat: format: unknown cloud format"):
        load_cloud(path)


# --------------------------------------------------------- files written by other tools


def test_float32_ply_with_extra_properties(tmp_path: Path) -> None:
    pts = np.random.default_rng(1).normal(size=(50, 3)).astype(np.float32)
    v = np.empty(50, dtype=[("intensity", "u1"), ("z", "f4"), ("x", "f4"), ("y", "f4")])
    v["x"], v["y"], v["z"], v["intensity"] = pts[:, 0], pts[:, 1], pts[:, 2], 7
    path = tmp_path / "f32.ply"
    plyfile.PlyData([plyfile.PlyElement.describe(v, "vertex")], byte_order=">").write(str(path))
    np.testing.assert_array_equal(load_cloud(path).points, pts.astype(np.float64))


@pytest.mark.parametrize("encoding", ["ascii", "binary", "binary_compressed"])
def test_float32_pcd_from_pypcd4(tmp_path: Path, encoding: str) -> None:
    pts = np.random.default_rng(2).normal(size=(40, 3)).astype(np.float32)
    path = tmp_path / "f32.pcd"
    pypcd4.PointCloud.from_xyz_points(pts).save(path, encoding=pypcd4.Encoding(encoding))
    np.testing.assert_allclose(load_cloud(path).points, pts.astype(np.float64), atol=1e-10)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("1 2 3\n4 5 6\n", [[1, 2, 3], [4, 5, 6]]),
        ("# scan\n\n1\t2   3 99\n4 5 6 99  # trailing comment\n", [[1, 2, 3], [4, 5, 6]]),
        ("1,2,3\n4,5,6", [[1, 2, 3], [4, 5, 6]]),
        ("1;2;3\n4;5;6\n", [[1, 2, 3], [4, 5, 6]]),
        ("X,Y,Z\n1,2,3\n", [[1, 2, 3]]),
        ('"i","z","x","y"\n0,3,1,2\n0,6,4,5\n', [[1, 2, 3], [4, 5, 6]]),
        ("-1e-3 +2.5E2 .5\n", [[-1e-3, 250.0, 0.5]]),
    ],
)
def test_text_variants(tmp_path: Path, text: str, expected: list) -> None:
    path = tmp_path / "pts.csv"
    path.write_text(text)
    np.testing.assert_array_equal(load_cloud(path).points, expected)


def test_structured_npy(tmp_path: Path) -> None:
    arr = np.zeros(3, dtype=[("x", "f4"), ("y", "f8"), ("z", "i4"), ("t", "f8")])
    arr["x"], arr["y"], arr["z"] = [1, 2, 3], [4, 5, 6], [7, 8, 9]
    path = tmp_path / "s.npy"
    np.save(path, arr)
    np.testing.assert_array_equal(load_cloud(path).points, [[1, 4, 7], [2, 5, 8], [3, 6, 9]])


# ------------------------------------------------------------------ broken and bad files


CUT_PLY = (
    r"cut\.ply: (file: not a valid PLY file|header: not a valid PLY file: no 'end_header'"
    r"|element vertex: header declares 257 (vertex \(6168 bytes|data rows))"
)
CUT_PCD = r"cut\.pcd: (POINTS: header declares 257 points of 24 bytes|header: not a valid PCD)"
CUT_NPY = (
    r"cut\.npy: (shape: header declares shape \(257, 3\) of float64 \(6168 bytes\)"
    r"|header: not a valid NPY file)"
)


@pytest.mark.parametrize("ascii", [False, True])
def test_truncated_ply(tmp_path: Path, cloud: PointCloud, ascii: bool) -> None:
    good = tmp_path / "good.ply"
    save_cloud(cloud, good, ascii=ascii)
    data = good.read_bytes()
    header_end = data.index(b"end_header\n") + len(b"end_header\n")
    bad = tmp_path / "cut.ply"
    for cut in (len(data) - 200, header_end + 30, header_end, header_end - 20, 3):
        bad.write_bytes(data[:cut])
        with pytest.raises(
            CloudError,
            match=CUT_PLY,
        ):
            load_cloud(bad)


def test_truncated_pcd(tmp_path: Path, cloud: PointCloud) -> None:
    good = tmp_path / "good.pcd"
    save_cloud(cloud, good)
    data = good.read_bytes()
    body = data.index(b"DATA binary\n") + len(b"DATA binary\n")
    bad = tmp_path / "cut.pcd"
    bad.write_bytes(data[: body + 24 * 100])  # 100 whole points of 257
    with pytest.raises(
        CloudError,
        match=r"cut\.pcd: POINTS: header declares 257 points of 24 bytes .* holds 2400 bytes",
    ):
        load_cloud(bad)
    for cut in (body + 24 * 100 + 5, body - 10, 20):
        bad.write_bytes(data[:cut])
        with pytest.raises(
            CloudError,
            match=CUT_PCD,
        ):
            load_cloud(bad)


def test_truncated_ascii_pcd_at_a_row(tmp_path: Path, cloud: PointCloud) -> None:
    good = tmp_path / "good.pcd"
    save_cloud(cloud, good, ascii=True)
    lines = good.read_bytes().splitlines(keepends=True)
    bad = tmp_path / "cut.pcd"
    bad.write_bytes(b"".join(lines[:-7]))
    with pytest.raises(CloudError, match="POINTS: header declares 257 points, the file holds 250"):
        load_cloud(bad)


def test_truncated_npy(tmp_path: Path, cloud: PointCloud) -> None:
    good = tmp_path / "good.npy"
    save_cloud(cloud, good)
    data = good.read_bytes()
    bad = tmp_path / "cut.npy"
    for cut in (len(data) - 8, 40, 0):
        bad.write_bytes(data[:cut])
        with pytest.raises(
            CloudError,
            match=CUT_NPY,
        ):
            load_cloud(bad)


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_empty_file(tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"empty{suffix}"
    path.write_bytes(b"")
    with pytest.raises(CloudError, match=rf"empty\{suffix}: (file|points|header: not a valid)"):
        load_cloud(path)


def test_clouds_with_no_points(tmp_path: Path) -> None:
    v = np.empty(0, dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])
    ply = tmp_path / "zero.ply"
    plyfile.PlyData([plyfile.PlyElement.describe(v, "vertex")]).write(str(ply))
    with pytest.raises(CloudError, match=r"zero\.ply: points: the file holds no points"):
        load_cloud(ply)
    npy = tmp_path / "zero.npy"
    np.save(npy, np.zeros((0, 3)))
    with pytest.raises(CloudError, match="the file holds no points"):
        load_cloud(npy)
    csv = tmp_path / "head.csv"
    csv.write_text("x,y,z\n# nothing\n")
    with pytest.raises(CloudError, match="a header but no points"):
        load_cloud(csv)


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_nan_rows_are_counted_or_dropped(tmp_path: Path, suffix: str) -> None:
    pts = np.arange(15, dtype=float).reshape(5, 3)
    pts[1, 2] = np.nan
    pts[4, 0] = -np.inf
    path = tmp_path / f"nan{suffix}"
    # write through the libraries directly: PointCloud itself refuses NaN
    if suffix == ".npy":
        np.save(path, pts)
    elif suffix == ".ply":
        v = np.rec.fromarrays(pts.T, names="x,y,z")
        plyfile.PlyData([plyfile.PlyElement.describe(np.asarray(v), "vertex")]).write(str(path))
    elif suffix == ".pcd":
        pypcd4.PointCloud.from_points(pts, ("x", "y", "z"), (np.float64,) * 3).save(path)
    else:
        np.savetxt(path, pts, delimiter="," if suffix == ".csv" else " ")
    with pytest.raises(CloudError, match=r"points: 2 of 5 points are not finite .* point 1"):
        load_cloud(path)
    np.testing.assert_array_equal(load_cloud(path, drop_non_finite=True).points, pts[[0, 2, 3]])
    np.save(tmp_path / "all.npy", np.full((3, 3), np.nan))
    with pytest.raises(CloudError, match="3 of 3"):
        load_cloud(tmp_path / "all.npy", drop_non_finite=True)


def test_missing_fields(tmp_path: Path) -> None:
    v = np.zeros(4, dtype=[("x", "f8"), ("y", "f8"), ("intensity", "f4")])
    ply = tmp_path / "noz.ply"
    plyfile.PlyData([plyfile.PlyElement.describe(v, "vertex")]).write(str(ply))
    with pytest.raises(CloudError, match=r"noz\.ply: vertex\.z: missing property \['z'\]"):
        load_cloud(ply)
    face = np.zeros(1, dtype=[("vertex_indices", "i4", (3,))])
    nov = tmp_path / "novertex.ply"
    plyfile.PlyData([plyfile.PlyElement.describe(face, "face")]).write(str(nov))
    with pytest.raises(CloudError, match=r"novertex\.ply: vertex: no 'vertex' element"):
        load_cloud(nov)
    pcd = tmp_path / "noz.pcd"
    pypcd4.PointCloud.from_points(
        np.zeros((3, 3)), ("x", "y", "intensity"), (np.float32,) * 3
    ).save(pcd)
    with pytest.raises(CloudError, match=r"noz\.pcd: z: missing field"):
        load_cloud(pcd)
    csv = tmp_path / "noz.csv"
    csv.write_text("x,y,w\n1,2,3\n")
    with pytest.raises(CloudError, match=r"noz\.csv: line 1: header .* has no column \['z'\]"):
        load_cloud(csv)
    npy = tmp_path / "noz.npy"
    np.save(npy, np.zeros(2, dtype=[("x", "f8"), ("y", "f8")]))
    with pytest.raises(CloudError, match=r"noz\.npy: z: missing field"):
        load_cloud(npy)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("1 2 3\n4 5\n", r"line 2: 2 columns, expected 3"),
        ("# c\n1,2,3\n\n4,5,oops\n", r"line 4: not a number: 'oops'"),
        ("1 2\n3 4\n", r"line 1: expected at least 3 columns"),
    ],
)
def test_bad_text_rows(tmp_path: Path, text: str, match: str) -> None:
    path = tmp_path / "bad.txt"
    path.write_text(text)
    with pytest.raises(CloudError, match=rf"bad\.txt: {match}"):
        load_cloud(path)


def test_wrong_shapes_and_types(tmp_path: Path) -> None:
    for name, arr, match in [
        ("four.npy", np.zeros((5, 4)), r"points: expected shape \(N, 3\), got \(5, 4\)"),
        ("flat.npy", np.zeros(3), r"expected shape \(N, 3\), got \(3,\)"),
        ("cplx.npy", np.zeros((2, 3), complex), "expected real numbers"),
        ("text.npy", np.array([["a", "b", "c"]]), "expected real numbers"),
    ]:
        np.save(tmp_path / name, arr)
        with pytest.raises(CloudError, match=match):
            load_cloud(tmp_path / name)
    np.save(tmp_path / "obj.npy", np.array([[1, 2, 3]], dtype=object), allow_pickle=True)
    with pytest.raises(
        CloudError, match=r"obj\.npy: dtype: objects \(object\) are not coordinates"
    ):
        load_cloud(tmp_path / "obj.npy")
    (tmp_path / "bin.xyz").write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(CloudError, match=r"bin\.xyz: line 1: not UTF-8 text"):
        load_cloud(tmp_path / "bin.xyz")
    (tmp_path / "junk.ply").write_bytes(b"not a ply at all\n")
    with pytest.raises(CloudError, match=r"junk\.ply: (file|header): not a valid PLY"):
        load_cloud(tmp_path / "junk.ply")


def test_missing_paths_and_bad_targets(tmp_path: Path, cloud: PointCloud) -> None:
    with pytest.raises(CloudError, match=r"nothere\.ply: file: no such file"):
        load_cloud(tmp_path / "nothere.ply")
    (tmp_path / "dir.ply").mkdir()
    with pytest.raises(CloudError, match="not a regular file"):
        load_cloud(tmp_path / "dir.ply")
    with pytest.raises(CloudError, match="does not exist"):
        save_cloud(cloud, tmp_path / "no" / "such" / "dir.ply")
    with pytest.raises(CloudError, match="format: unknown cloud format"):
        save_cloud(cloud, tmp_path / "cloud.las")
    with pytest.raises(CloudError, match="expected a PointCloud"):
        save_cloud(np.zeros((2, 3)), tmp_path / "a.ply")  # type: ignore[arg-type]


# ---------------------------------------------------------------------------- meshes


@pytest.mark.parametrize("suffix", [".stl", ".obj", ".ply", ".off"])
def test_mesh_cloud_lies_on_the_mesh(tmp_path: Path, suffix: str) -> None:
    extents = np.array([0.2, 0.5, 1.0])
    path = tmp_path / f"part{suffix}"
    trimesh.creation.box(extents=extents).export(path)
    a = load_mesh_cloud(path, n=1000, seed=1, frame="link_2")
    assert len(a) == 1000 and a.frame == "link_2" and a.name == str(path)
    gap = np.min(extents / 2 - np.abs(a.points), axis=1)  # distance to the box surface
    assert np.abs(gap).max() < 1e-6  # exported coordinates may be float32 (STL)
    np.testing.assert_array_equal(a.points, load_mesh_cloud(path, n=1000, seed=1).points)


def test_mesh_cloud_scale(tmp_path: Path) -> None:
    path = tmp_path / "mm.stl"
    trimesh.creation.box(extents=(200.0, 500.0, 1000.0)).export(path)
    pts = load_mesh_cloud(path, n=200, seed=0, scale=0.001).points
    np.testing.assert_allclose(np.abs(pts).max(axis=0), [0.1, 0.25, 0.5], atol=0.03)
    with pytest.raises(CloudError, match="scale"):
        load_mesh_cloud(path, scale=0.0)


def test_broken_meshes(tmp_path: Path) -> None:
    good = tmp_path / "good.stl"
    trimesh.creation.icosphere(subdivisions=1).export(good)
    data = good.read_bytes()
    bad = tmp_path / "cut.stl"
    bad.write_bytes(data[:-7])
    with pytest.raises(CloudError, match=r"cut\.stl: file: binary STL header declares 80 .*trunc"):
        load_mesh_cloud(bad)
    bad.write_bytes(data[:50])
    with pytest.raises(CloudError, match="too short for an STL file"):
        load_mesh_cloud(bad)
    empty = tmp_path / "empty.obj"
    empty.write_text("")
    with pytest.raises(CloudError, match=r"empty\.obj: faces: no triangles could be read"):
        load_mesh_cloud(empty)
    pts = tmp_path / "points.ply"
    save_cloud(PointCloud(np.eye(3)), pts)
    with pytest.raises(CloudError, match=r"points\.ply: faces: no triangles"):
        load_mesh_cloud(pts)
    other = tmp_path / "part.step"
    other.write_text("ISO-10303-21;")
    with pytest.raises(CloudError, match=r"part\.step: format: unknown mesh suffix"):
        load_mesh_cloud(other)
    garbage = tmp_path / "garbage.obj"
    garbage.write_text("v 0 0 0\nv 1 0 0\nf 1 2 9\n")
    with pytest.raises(CloudError, match=r"garbage\.obj: (file|faces)"):
        load_mesh_cloud(garbage)
    with pytest.raises(CloudError, match="no such file"):
        load_mesh_cloud(tmp_path / "gone.stl")
