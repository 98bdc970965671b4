"""Occlusion-aware scans (issue 9): the virtual points that fill the space behind the
scanned surfaces, checked against their rays and by casting rays at the true meshes."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree
from typer.testing import CliRunner

from reachwise.cli import app
from reachwise.errors import InputError
from reachwise.geometry.cloud import PointCloud, voxel_keys
from reachwise.geometry.occlusion import OcclusionFill, shadow_points
from reachwise.geometry.raycast import cast_rays
from reachwise.geometry.scan_scene import scan_scene
from reachwise.sim.p5_scenes import get_scene

finite = st.floats(-10.0, 10.0, allow_nan=False)


@given(
    st.tuples(finite, finite, finite),
    st.lists(st.tuples(finite, finite, finite), min_size=1, max_size=20),
    st.floats(0.05, 2.0),
    st.floats(0.01, 0.3),
)
@settings(max_examples=80, deadline=None)
def test_every_virtual_point_lies_on_its_ray_behind_its_hit(  # type: ignore[type-arg]
    origin: tuple, hits: list, depth: float, spacing: float
) -> None:
    o = np.array(origin)
    h = np.array(hits)
    r = np.linalg.norm(h - o, axis=1)
    # a hit at the origin, or a real range: not 1e-160 m, whose square underflows and
    # makes this test's own unit vector inexact
    assume(np.all((r == 0.0) | (r > 1e-6)))
    pts, ray = shadow_points(o, h, depth, spacing)
    # count per ray: floor(depth / spacing) samples, none for a hit at the origin
    want = np.where(r > 0, np.floor(depth / spacing + 1e-9), 0).astype(int)
    np.testing.assert_array_equal(np.bincount(ray, minlength=len(h)), want)
    if len(pts) == 0:
        return
    d = (h[ray] - o) / r[ray, None]
    rel = pts - o
    along = np.einsum("ij,ij->i", rel, d)
    off = np.linalg.norm(rel - along[:, None] * d, axis=1)
    assert np.all(off <= 1e-9 * (1 + np.abs(along)))  # on the ray
    behind = along - r[ray]
    assert np.all(behind > 0.0) and np.all(behind <= depth + 1e-9)  # behind its hit
    # spaced by `spacing` from the hit on
    k = np.round(behind / spacing)
    np.testing.assert_allclose(behind, k * spacing, atol=1e-9)


@given(
    st.lists(st.tuples(finite, finite, st.floats(-1.0, 3.0)), min_size=1, max_size=20),
    st.floats(0.1, 3.0),
)
@settings(max_examples=60, deadline=None)
def test_nothing_goes_under_the_ground(hits: list, depth: float) -> None:  # type: ignore[type-arg]
    o = np.array([0.0, 0.0, 2.5])
    h = np.array(hits)
    pts, ray = shadow_points(o, h, depth, 0.03, ground=0.0)
    assert np.all(pts[:, 2] >= -1e-12)
    assert not np.isin(ray, np.flatnonzero(h[:, 2] < 0.0)).any()
    # a ray stops at the ground: as many samples as fit above it (or in `depth`)
    r = np.linalg.norm(h - o, axis=1)
    dz = (h[:, 2] - o[2]) / np.where(r > 0, r, 1.0)
    room = np.where(dz < 0, h[:, 2] / np.where(dz < 0, -dz, 1.0), np.inf)
    want = np.where((r > 0) & (h[:, 2] >= 0), np.floor(np.minimum(depth, room) / 0.03 + 1e-9), 0)
    np.testing.assert_array_equal(np.bincount(ray, minlength=len(h)), want.astype(int))


@pytest.fixture(scope="module")
def coarse_p5():  # type: ignore[no-untyped-def]
    scene = get_scene("p5-floor-obstacle")
    raw, _ = scan_scene(scene, coarsen=4.0)
    return scene, raw


def test_no_virtual_point_lies_in_front_of_an_observed_surface(coarse_p5) -> None:  # type: ignore[no-untyped-def]
    """Independent check with the true meshes: the first surface a ray from the scanner
    towards a virtual point meets lies no farther than the point itself (the point is
    occluded), and its own beam's hit lies in front of it."""
    scene, raw = coarse_p5
    pts, ray = raw.shadow(0.6, 0.05, ground=0.0)
    assert len(pts) > 1000
    rng = np.random.default_rng(0)
    pick = rng.choice(len(pts), 600, replace=False)
    p = pts[pick]
    o = np.broadcast_to(raw.origin, p.shape)
    hit, dist = cast_rays(list(scene.meshes), o, p - o)
    rng_p = np.linalg.norm(p - raw.origin, axis=1)
    assert hit.all()
    assert np.all(dist <= rng_p + 1e-9)
    assert np.all(raw.ranges[ray[pick]] < rng_p)


def test_the_fill_reaches_behind_the_box_and_keeps_every_measured_point(coarse_p5) -> None:  # type: ignore[no-untyped-def]
    scene, raw = coarse_p5
    plain = scene.process(raw.cloud)
    virtual = scene.virtual_points(raw, OcclusionFill(1.0))
    filled = scene.process(raw.cloud, virtual)
    # every measured point survives, virtual ones only in voxels no measured point holds
    have = {tuple(p) for p in filled.points.tolist()}
    assert all(tuple(p) in have for p in plain.points.tolist())
    keys = {tuple(k) for k in voxel_keys(plain, scene.voxel, scene.crop_min).tolist()}
    extra = filled.points[len(plain) :]
    assert len(extra) > 0
    extra_keys = voxel_keys(extra, scene.voxel, scene.crop_min).tolist()
    assert not any(tuple(k) in keys for k in extra_keys)
    assert len(set(map(tuple, extra_keys))) == len(extra)  # one point per voxel
    # the unseen back face (x = 3.05) is now covered, up to the box's height
    lo, hi = scene.obstacles[0]
    yy, zz = np.meshgrid(np.linspace(lo[1], hi[1], 9), np.linspace(0.05, hi[2] - 0.05, 5))
    back = np.column_stack([np.full(yy.size, hi[0]), yy.ravel(), zz.ravel()])
    assert cKDTree(filled.points).query(back)[0].max() < 0.12
    assert cKDTree(plain.points).query(back)[0].max() > 0.2


def test_a_head_on_fill_rebuilds_the_unseen_box() -> None:
    """p5-occlusion sees only the box's front face; a fill as deep as the box puts
    points on its back face and sides (within a voxel and the beams' spread)."""
    scene = get_scene("p5-occlusion")
    _, plain = scan_scene(scene, coarsen=2.0)
    _, filled = scan_scene(scene, coarsen=2.0, occlusion=OcclusionFill(0.7))
    lo, hi = scene.obstacles[0]
    box = plain.points[plain.points[:, 2] > 0.05]
    np.testing.assert_allclose(box[:, 0], lo[0], atol=1e-9)  # front face only
    g = np.linspace(0.05, 0.95, 7)
    faces = []
    for y in g * (hi[1] - lo[1]) + lo[1]:
        for z in g * hi[2]:
            faces.append([hi[0] - 0.02, y, z])  # back face
    for x in g * (hi[0] - lo[0]) + lo[0]:
        for z in g * hi[2]:
            faces += [[x, lo[1], z], [x, hi[1], z]]  # sides
    faces_a = np.array(faces)
    d_fill = cKDTree(filled.points).query(faces_a)[0]
    d_plain = cKDTree(plain.points).query(faces_a)[0]
    assert d_fill.max() < 0.12, d_fill.max()
    assert np.median(d_plain) > 0.3
    # nothing virtual in front of the front face or below the floor
    assert filled.points[:, 2].min() >= -1e-9
    assert np.all(filled.points[filled.points[:, 2] > 0.05][:, 0] >= lo[0] - 1e-9)


def test_interior_voxels_of_the_fill_are_dropped() -> None:
    scene = get_scene("p5-occlusion")
    raw, _ = scan_scene(scene, coarsen=2.0)
    virtual = scene.virtual_points(raw, OcclusionFill(0.7))
    filled = scene.process(raw.cloud, virtual)
    keys = voxel_keys(filled, scene.voxel, scene.crop_min)
    occupied = {tuple(k) for k in keys.tolist()}
    steps = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])
    n_measured = len(scene.process(raw.cloud))
    assert len(keys) - n_measured > 100  # the fill adds voxels here: the loop checks some
    for k in keys[n_measured:]:
        assert not all(tuple(k + s) in occupied for s in steps)


@pytest.mark.parametrize(("width", "height", "depth"), [(6, 5, 4), (3, 3, 1), (8, 2, 3)])
def test_a_filled_block_keeps_exactly_its_boundary_voxels(
    width: int, height: int, depth: int
) -> None:
    """A measured wall of ``width x height`` voxels with a fill ``depth`` voxels deep
    behind it: the fill keeps the block's boundary voxels, all
    ``D W H - (D - 1)(W - 2)(H - 2)`` of them (the interior ones have six occupied
    neighbours), and never a voxel of the wall itself."""
    scene = get_scene("p5-occlusion")
    v = scene.voxel
    base = np.array([60, 20, 10])  # a voxel well inside the crop box

    def centres(i: range, j: range, k: range) -> np.ndarray:
        idx = np.array([(a, b, c) for a in i for b in j for c in k]) + base
        return scene.crop_min + (idx + 0.5) * v

    wall = centres(range(1), range(width), range(height))
    fill = centres(range(1, depth + 1), range(width), range(height))
    fill = np.vstack([fill, wall])  # a fill point on a measured voxel is never kept
    out = scene.process(PointCloud(wall), fill)
    interior = max(depth - 1, 0) * max(width - 2, 0) * max(height - 2, 0)
    assert len(out) == width * height + depth * width * height - interior
    np.testing.assert_array_equal(out.points[: width * height], wall)


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda: shadow_points([0, 0, 0], [[1, 0, 0]], 0.0), "depth"),
        (lambda: shadow_points([0, 0, 0], [[1, 0, 0]], 1.0, -0.1), "spacing"),
        (lambda: shadow_points([0, 0, 0], [[1, 0, 0]], 1.0, 1e-6), "spacing"),
        (lambda: shadow_points([0, 0], [[1, 0, 0]], 1.0), "origin"),
        (lambda: shadow_points([0, 0, 0], [[1, 0, math.nan]], 1.0), "hits"),
        (lambda: OcclusionFill(depth=-1.0), "depth"),
        (lambda: OcclusionFill(spacing=0.0), "spacing"),
    ],
)
def test_bad_input_is_named(call, field: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(InputError, match=field):
        call()


def test_scan_cli_occlusion_option(tmp_path) -> None:  # type: ignore[no-untyped-def]
    runner = CliRunner()
    args = ["scan", "p5-occlusion", "--coarsen", "3", "--json"]
    plain = runner.invoke(app, [*args, "--out", str(tmp_path / "a.npy")])
    filled = runner.invoke(
        app, [*args, "--out", str(tmp_path / "b.npy"), "--occlusion-depth", "0.7"]
    )
    raw = runner.invoke(
        app, [*args, "--out", str(tmp_path / "c.npy"), "--occlusion-depth", "0.7", "--raw"]
    )
    assert plain.exit_code == 0 and filled.exit_code == 0 and raw.exit_code == 0, filled.stdout
    a, b, c = (json.loads(r.stdout) for r in (plain, filled, raw))
    assert a["occlusion_depth"] is None and b["occlusion_depth"] == 0.7
    assert b["points"] > a["points"]
    assert c["points"] == c["returns"] + c["virtual"] and c["virtual"] > 0
    pa, pb = np.load(tmp_path / "a.npy"), np.load(tmp_path / "b.npy")
    have = {tuple(p) for p in pb.tolist()}
    assert all(tuple(p) in have for p in pa.tolist())
