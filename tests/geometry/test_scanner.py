"""The simulated P-V laser scanner against analytic geometry (planes, slabs, shadows)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from reachwise.errors import CloudError, InputError
from reachwise.geometry.raycast import cast_rays
from reachwise.geometry.scan_scene import scan_scene
from reachwise.geometry.scanner import LaserScanner
from reachwise.sim.p5_scenes import get_scene, p5_floor_obstacle

ENGINES = ["triangle"] + (["embree"] if trimesh.ray.has_embree else [])


def floor_mesh(half: float = 50.0, z: float = 0.0) -> trimesh.Trimesh:
    v = [[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]]
    return trimesh.Trimesh(vertices=v, faces=[[0, 1, 2], [0, 2, 3]], process=False)


def pose_at(xyz, R=None) -> np.ndarray:
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    T[:3, 3] = xyz
    return T


def small_scanner(**kw) -> LaserScanner:
    """A coarse scanner for quick tests: 2° beams, 2° lines."""
    base = {
        "pose": pose_at((0.0, 0.0, 2.0)),
        "angular_resolution": math.radians(2.0),
        "tilt_rate": math.radians(50.0),
        "azimuth_range": (math.radians(-40), math.radians(40)),
        "tilt_range": (math.radians(15), math.radians(70)),
    }
    base.update(kw)
    return LaserScanner(**base)


def segment_hits_box(o: np.ndarray, q: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Slab test: does the open segment o->q pass through the box interior (lo, hi)?"""
    d = q - o
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (lo - o) / d
        t2 = (hi - o) / d
    tmin = np.where(d == 0, np.where((o > lo) & (o < hi), -np.inf, np.inf), np.minimum(t1, t2))
    tmax = np.where(d == 0, np.where((o > lo) & (o < hi), np.inf, -np.inf), np.maximum(t1, t2))
    enter = tmin.max(axis=-1)
    leave = tmax.min(axis=-1)
    return (enter < leave) & (leave > 0) & (enter < 1)


# ------------------------------------------------------------------------ beam geometry


def test_defaults_are_the_p5_rig() -> None:
    s = LaserScanner()
    assert math.isclose(math.degrees(s.angular_resolution), 0.25)
    assert s.scan_rate == 25.0
    assert math.isclose(math.degrees(s.tilt_rate), 5.0)
    # P-V §IV: 5°/s at 25 Hz "resulted in a vertical resolution of 0.2 degrees"
    assert math.isclose(math.degrees(s.line_spacing), 0.2)
    t, tilt, az = s.beams()
    assert len(t) == s.n_rays == s.n_beams * s.n_lines
    first_line = az[: s.n_beams]
    np.testing.assert_allclose(np.diff(first_line), math.radians(0.25), rtol=1e-12)
    line_starts = tilt[:: s.n_beams]
    np.testing.assert_allclose(np.diff(line_starts), math.radians(0.2), rtol=1e-9)
    # the tilt keeps turning during a line: tilt = start + rate * firing time
    np.testing.assert_allclose(tilt, s.tilt_range[0] + s.tilt_rate * t, rtol=0, atol=1e-15)
    assert np.all(np.diff(t) > 0)


def test_positive_tilt_looks_down_and_azimuth_left() -> None:
    s = LaserScanner()
    d = s.directions([math.radians(30.0), 0.0], [0.0, math.radians(90.0)])
    np.testing.assert_allclose(d[0], [math.cos(math.radians(30)), 0, -0.5], atol=1e-15)
    np.testing.assert_allclose(d[1], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(s.directions(), axis=1), 1.0, rtol=1e-14)


def test_coarsened_reduces_rays() -> None:
    s = LaserScanner()
    c = s.coarsened(4)
    assert math.isclose(c.angular_resolution, 4 * s.angular_resolution)
    assert math.isclose(c.line_spacing, 4 * s.line_spacing)
    assert c.n_rays < s.n_rays / 12


@pytest.mark.parametrize(
    ("kw", "field"),
    [
        ({"angular_resolution": 0.0}, "angular_resolution"),
        ({"scan_rate": -25.0}, "scan_rate"),
        ({"tilt_rate": float("nan")}, "tilt_rate"),
        ({"azimuth_range": (1.0, 0.0)}, "azimuth_range"),
        ({"azimuth_range": (-4.0, 4.0)}, "azimuth_range"),
        ({"tilt_range": (0.1,)}, "tilt_range"),
        ({"max_range": 0.0}, "max_range"),
        ({"min_range": 5.0, "max_range": 2.0}, "min_range"),
        ({"range_noise": -0.01}, "range_noise"),
        ({"pose": np.diag([1.0, 1.0, -1.0, 1.0])}, "pose"),
        ({"pose": np.eye(3)}, "pose"),
    ],
)
def test_scanner_rejects_bad_parameters(kw: dict, field: str) -> None:
    with pytest.raises(InputError, match=f"scanner: {field}"):
        LaserScanner(**kw)


# -------------------------------------------------------------------------- ray casting


@pytest.mark.parametrize("engine", ENGINES)
def test_cast_rays_matches_the_slab_method(engine: str) -> None:
    rng = np.random.default_rng(11)
    lo, hi = np.array([-0.3, -0.5, -0.2]), np.array([0.4, 0.5, 0.6])
    box = trimesh.creation.box(bounds=[lo, hi])
    n = 3000
    o = rng.uniform(-3, 3, (n, 3))
    o[np.all((o > lo - 0.05) & (o < hi + 0.05), axis=1)] += 2.0  # start outside
    target = rng.uniform(lo - 0.3, hi + 0.3, (n, 3))
    d = target - o
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    hit, dist = cast_rays(box, o, d, engine=engine)  # type: ignore[arg-type]
    # analytic entry distance (slab method)
    with np.errstate(divide="ignore"):
        t1, t2 = (lo - o) / d, (hi - o) / d
    enter = np.minimum(t1, t2).max(axis=1)
    leave = np.maximum(t1, t2).min(axis=1)
    truth = (enter < leave) & (enter > 0)
    clear = np.abs(leave - enter) > 1e-6  # skip grazing rays along edges and corners
    assert truth[clear].sum() > 500
    np.testing.assert_array_equal(hit[clear], truth[clear])
    np.testing.assert_allclose(dist[clear & truth], enter[clear & truth], rtol=0, atol=1e-12)
    assert np.all(np.isinf(dist[~hit]))


def test_engines_agree() -> None:
    if not trimesh.ray.has_embree:
        pytest.skip("embreex not installed")
    sc = p5_floor_obstacle()
    s = sc.scanner.coarsened(4)
    a = s.scan(list(sc.meshes), engine="triangle").points
    b = s.scan(list(sc.meshes), engine="embree").points
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)


# ------------------------------------------------------------------------------ planes


@pytest.mark.parametrize("engine", ENGINES)
def test_scanned_floor_points_lie_on_the_floor(engine: str) -> None:
    s = small_scanner()
    scan = s.scan(floor_mesh(), engine=engine)  # type: ignore[arg-type]
    assert len(scan.cloud) == s.n_rays  # every beam looks down onto the floor
    np.testing.assert_allclose(scan.points[:, 2], 0.0, atol=1e-12)
    # range to a plane h below the scanner along a unit beam d: h / -d_z
    np.testing.assert_allclose(scan.ranges, 2.0 / -scan.directions[:, 2], rtol=1e-12)


def test_tilted_plane_points_lie_on_it_within_the_noise() -> None:
    rng = np.random.default_rng(5)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    angle = 0.4
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    R = np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K
    plane = floor_mesh(20.0)
    plane.apply_transform(pose_at((0.3, -0.2, -0.5), R))
    normal, point = R[:, 2], np.array([0.3, -0.2, -0.5])
    sigma = 0.01
    s = small_scanner(range_noise=sigma)
    scan = s.scan(plane, rng=np.random.default_rng(9))
    residual = (scan.points - point) @ normal
    # the noise is along the beam: the offset from the plane is noise * (d . n)
    cos_incidence = np.abs(scan.directions @ normal)
    assert np.all(np.abs(residual) <= 5 * sigma * cos_incidence + 1e-12)
    along = residual / (scan.directions @ normal)
    assert 0.8 * sigma < np.std(along) < 1.2 * sigma
    noiseless = small_scanner().scan(plane)
    assert np.abs((noiseless.points - point) @ normal).max() < 1e-9


def test_noise_is_reproducible_and_needs_a_generator() -> None:
    s = small_scanner(range_noise=0.02)
    a = s.scan(floor_mesh(), rng=np.random.default_rng(3)).points
    b = s.scan(floor_mesh(), rng=3).points
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, s.scan(floor_mesh(), rng=4).points)
    with pytest.raises(InputError, match="scanner: rng"):
        s.scan(floor_mesh())


def test_range_limits_drop_returns() -> None:
    s = small_scanner(min_range=2.5, max_range=4.0)
    scan = s.scan(floor_mesh())
    full = small_scanner().scan(floor_mesh())
    expect = (full.ranges >= 2.5) & (full.ranges <= 4.0)
    assert 0 < len(scan.cloud) == expect.sum() < len(full.cloud)
    np.testing.assert_array_equal(scan.ranges, full.ranges[expect])
    with pytest.raises(CloudError, match="none of"):
        small_scanner(max_range=1.0).scan(floor_mesh())


# ------------------------------------------------------------------- shadow of a box


def test_no_point_lies_in_the_shadow_behind_a_box() -> None:
    sc = p5_floor_obstacle()
    lo, hi = sc.obstacles[0]
    h = sc.scanner.origin[2]
    scan = sc.scanner.coarsened(2).scan(list(sc.meshes))
    o, p = scan.origin, scan.points
    # every measured point is visible: the segment to it never crosses the box interior
    assert not segment_hits_box(o, p, lo + 1e-9, hi - 1e-9).any()
    on_floor = np.abs(p[:, 2]) < 1e-9
    on_box = ~on_floor
    assert on_box.sum() > 100
    # box points lie on the box's faces the scanner can see: top and front (x = lo),
    # the sides facing it; none on the far face or under the box
    assert np.all((p[on_box] >= lo - 1e-9).all(axis=1) & (p[on_box] <= hi + 1e-9).all(axis=1))
    assert not np.any(np.isclose(p[on_box, 0], hi[0], atol=1e-9) & (p[on_box, 2] < hi[2] - 1e-6))
    floor = p[on_floor]
    assert not np.any(np.all((floor[:, :2] > lo[:2]) & (floor[:, :2] < hi[:2]), axis=1))
    # the shadow is there and empty: on the centre line it runs from the far top edge
    # (x = hi_x, z = hi_z) to where the beam over that edge meets the floor
    x_end = hi[0] * h / (h - hi[2])
    strip = floor[np.abs(floor[:, 1]) < 0.1]
    assert not np.any((strip[:, 0] > hi[0]) & (strip[:, 0] < x_end - 1e-9))
    assert np.any((strip[:, 0] > x_end) & (strip[:, 0] < x_end + 0.15))  # seen again
    # and the analytic shadow region holds floor that would be seen without the box
    grid = np.stack(np.meshgrid(np.linspace(1.5, 4, 60), np.linspace(-1, 1, 60)), -1)
    grid = np.column_stack([grid.reshape(-1, 2), np.zeros(3600)])
    shadow = segment_hits_box(o, grid, lo, hi) & ~np.all(
        (grid[:, :2] >= lo[:2]) & (grid[:, :2] <= hi[:2]), axis=1
    )
    assert shadow.sum() > 50


# ------------------------------------------------------------------------- the P-V scene


def test_p5_scene_gives_about_5500_points() -> None:
    sc = get_scene("p5-floor-obstacle")
    raw, cloud = scan_scene(sc)
    assert raw.n_rays == sc.scanner.n_rays
    assert 5000 <= len(cloud) <= 6000  # P-V §IV: "approximately 5500"
    assert np.all(cloud.points >= sc.crop_min) and np.all(cloud.points <= sc.crop_max)
    # at most one point per 3 cm voxel of the working area
    keys = np.floor((cloud.points - sc.crop_min) / sc.voxel)
    assert len(np.unique(keys, axis=0)) == len(cloud)
    # the obstacle is in it, and the shadow behind it is empty
    lo, hi = sc.obstacles[0]
    assert np.sum(cloud.points[:, 2] > 0.05) > 500
    assert not segment_hits_box(raw.origin, cloud.points, lo + 1e-9, hi - 1e-9).any()


def test_scan_scene_options() -> None:
    raw, cloud = scan_scene(get_scene("p5-floor-obstacle"), 1, noise=0.005, coarsen=3)
    assert raw.n_rays < 10_000 and len(cloud) < len(raw.cloud)
    raw2, _ = scan_scene(get_scene("p5-floor-obstacle"), 1, noise=0.005, coarsen=3)
    np.testing.assert_array_equal(raw.points, raw2.points)
    with pytest.raises(InputError, match="unknown scene 'rock'"):
        get_scene("rock")
    with pytest.raises(InputError, match="meshes"):
        small_scanner().scan([])


def test_meshes_as_vertex_face_pairs() -> None:
    m = floor_mesh()
    box = trimesh.creation.box(bounds=[[1, -0.5, 0], [2, 0.5, 1]])
    a = small_scanner().scan([m, box]).points
    b = small_scanner().scan([(m.vertices, m.faces), (box.vertices.tolist(), box.faces)]).points
    np.testing.assert_array_equal(a, b)
    c = small_scanner().scan((m.vertices, m.faces)).points
    np.testing.assert_array_equal(c, small_scanner().scan(m).points)
    for bad, match in [
        ([(m.vertices, m.faces + 10)], r"meshes\[0\]: face indices"),
        ([(m.vertices[:, :2], m.faces)], r"meshes\[0\]: vertices must be finite \(V, 3\)"),
        ([m, (m.vertices, m.faces.astype(float))], r"meshes\[1\]: faces must be integer"),
        ([m, "floor"], r"meshes\[1\]: expected a Trimesh"),
    ]:
        with pytest.raises(InputError, match=match):
            small_scanner().scan(bad)
