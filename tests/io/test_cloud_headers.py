"""Cloud file headers checked against the bytes they describe: each case of a header
that promises too much, too little or the wrong thing is a CloudError naming the file
and the header field, raised before the points are allocated."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from reachwise.errors import CloudError
from reachwise.geometry.cloud import PointCloud
from reachwise.io.cloud_headers import TEXT_ROW_BYTES
from reachwise.io.clouds import load_cloud, save_cloud

N = 40


@pytest.fixture
def pts() -> np.ndarray:
    return np.random.default_rng(32).uniform(-1.0, 1.0, (N, 3))


def _ply(path: Path, pts: np.ndarray, count: int, ascii: bool, xtype: str = "double") -> Path:
    fmt = "ascii" if ascii else "binary_little_endian"
    head = (
        f"ply\nformat {fmt} 1.0\nelement vertex {count}\nproperty {xtype} x\n"
        "property double y\nproperty double z\nend_header\n"
    )
    body = (
        "".join(" ".join(repr(float(v)) for v in p) + "\n" for p in pts).encode()
        if ascii
        else pts.astype("<f8").tobytes()
    )
    path.write_bytes(head.encode() + body)
    return path


def _pcd(path: Path, pts: np.ndarray, **head: str) -> Path:
    fields = {"VERSION": "0.7", "FIELDS": "x y z", "SIZE": "8 8 8", "TYPE": "F F F",
              "COUNT": "1 1 1", "WIDTH": str(len(pts)), "HEIGHT": "1",
              "VIEWPOINT": "0 0 0 1 0 0 0", "POINTS": str(len(pts)), "DATA": "binary"}  # fmt: skip
    fields.update(head)
    text = "".join(f"{k} {v}\n" for k, v in fields.items())
    path.write_bytes(text.encode() + pts.astype("<f8").tobytes())
    return path


def _npy(path: Path, pts: np.ndarray, shape: tuple[int, ...]) -> Path:
    header = {"descr": "<f8", "fortran_order": False, "shape": shape}
    with open(path, "wb") as fh:
        np.lib.format.write_array_header_1_0(fh, header)
        fh.write(pts.astype("<f8").tobytes())
    return path


def _refused(path: Path, field: str, match: str, **kw: int) -> CloudError:
    with pytest.raises(CloudError, match=match) as info:
        load_cloud(path, **kw)  # type: ignore[arg-type]
    assert info.value.source == str(path) and info.value.field == field
    return info.value


@pytest.mark.parametrize("ascii", [False, True])
def test_ply_valid_file_loads(tmp_path: Path, pts: np.ndarray, ascii: bool) -> None:
    cloud = load_cloud(_ply(tmp_path / "ok.ply", pts, N, ascii))
    np.testing.assert_array_equal(cloud.points, pts)


def test_ply_declaring_four_billion_vertices_is_refused(tmp_path: Path, pts: np.ndarray) -> None:
    path = _ply(tmp_path / "huge.ply", pts, 4_000_000_000, ascii=False)
    _refused(path, "element vertex", "declares 4000000000 points, more than the bound")


@pytest.mark.parametrize("ascii", [False, True])
def test_ply_declaring_fewer_vertices_than_it_holds(
    tmp_path: Path, pts: np.ndarray, ascii: bool
) -> None:
    path = _ply(tmp_path / "short.ply", pts, N - 1, ascii)
    _refused(path, "element vertex", "header declares 39")


@pytest.mark.parametrize("ascii", [False, True])
def test_ply_declaring_more_vertices_than_it_holds(
    tmp_path: Path, pts: np.ndarray, ascii: bool
) -> None:
    path = _ply(tmp_path / "long.ply", pts, N + 1, ascii)
    _refused(path, "element vertex", "header declares 41")


@pytest.mark.parametrize("xtype", ["char", "uchar", "int8"])
def test_ply_char_coordinate_over_double_data(tmp_path: Path, pts: np.ndarray, xtype: str) -> None:
    path = _ply(tmp_path / "char.ply", pts, N, ascii=False, xtype=xtype)
    _refused(path, "vertex.x", "a coordinate cannot be")


def test_ply_float_coordinate_over_double_data(tmp_path: Path, pts: np.ndarray) -> None:
    path = _ply(tmp_path / "f4.ply", pts, N, ascii=False, xtype="float")
    _refused(path, "element vertex", r"\(800 bytes of data\), the file holds 960 bytes")


def test_npy_shape_promising_fewer_points(tmp_path: Path, pts: np.ndarray) -> None:
    path = _npy(tmp_path / "short.npy", pts, (N - 1, 3))
    _refused(path, "shape", r"shape \(39, 3\) of float64 \(936 bytes\), the file holds 960")


def test_npy_shape_of_fifty_billion_points(tmp_path: Path, pts: np.ndarray) -> None:
    path = _npy(tmp_path / "huge.npy", pts, (50_000_000_000, 3))
    _refused(path, "shape", "declares 50000000000 points, more than the bound")


def test_pcd_width_times_height_must_be_points(tmp_path: Path, pts: np.ndarray) -> None:
    path = _pcd(tmp_path / "wide.pcd", pts, WIDTH="41")
    _refused(path, "WIDTH", "WIDTH 41 x HEIGHT 1 is not POINTS 40")


def test_pcd_sizes_not_matching_the_data(tmp_path: Path, pts: np.ndarray) -> None:
    path = _pcd(tmp_path / "size.pcd", pts, SIZE="8 8 4")
    _refused(path, "POINTS", r"40 points of 20 bytes \(800 bytes\), the file holds 960 bytes")


def test_pcd_header_lists_must_match_the_fields(tmp_path: Path, pts: np.ndarray) -> None:
    _refused(_pcd(tmp_path / "a.pcd", pts, TYPE="F F"), "TYPE", "2 values for 3 fields")
    _refused(_pcd(tmp_path / "b.pcd", pts, SIZE="3 8 8"), "x", "SIZE 3 TYPE F COUNT 1")


def test_pcd_points_beyond_the_bound(tmp_path: Path, pts: np.ndarray) -> None:
    path = _pcd(tmp_path / "huge.pcd", pts, WIDTH="4000000000", POINTS="4000000000")
    _refused(path, "POINTS", "declares 4000000000 points, more than the bound")


@pytest.mark.parametrize("suffix", [".ply", ".pcd", ".npy", ".xyz", ".csv"])
def test_max_points_is_a_bound_the_user_can_raise(
    tmp_path: Path, pts: np.ndarray, suffix: str
) -> None:
    path = save_cloud(PointCloud(pts), tmp_path / f"c{suffix}")
    with pytest.raises(CloudError, match="more than the bound 39") as info:
        load_cloud(path, max_points=N - 1)
    assert info.value.source == str(path)
    np.testing.assert_array_equal(load_cloud(path, max_points=N).points, pts)


@pytest.mark.parametrize("suffix", [".xyz", ".csv"])
def test_text_cloud_larger_than_its_byte_bound_is_refused_unread(
    tmp_path: Path, pts: np.ndarray, suffix: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A text file states no count: its size against ``max_points`` rows of
    TEXT_ROW_BYTES is the bound, checked before a byte is read."""
    path = save_cloud(PointCloud(pts[:10]), tmp_path / f"c{suffix}")
    path.write_bytes(path.read_bytes() + b"#" + b"x" * 70_000 + b"\n")  # a long comment
    limit = 64 * 1024 + 10 * TEXT_ROW_BYTES
    assert path.stat().st_size > limit

    def no_read(self: Path) -> bytes:
        raise AssertionError(f"{self} read")

    with monkeypatch.context() as m:
        m.setattr(Path, "read_bytes", no_read)
        err = _refused(path, "file", f"more than {limit}: 10 points", max_points=10)
    assert "--max-points" in str(err)
    np.testing.assert_array_equal(load_cloud(path, max_points=100).points, pts[:10])
