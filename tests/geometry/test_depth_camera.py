"""The depth camera model against analytic scenes: planes and spheres at known places."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from reachwise.errors import InputError
from reachwise.geometry.depth_camera import DepthCamera, Intrinsics


def looking_along_x(position: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """Camera → world pose: the optical axis (camera z) along world +x, image x along
    world −y, image y (down) along world −z."""
    T = np.eye(4)
    T[:3, :3] = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    T[:3, 3] = position
    return T


def wall(x: float, half: float = 50.0) -> trimesh.Trimesh:
    """A plane x = const, 2·half wide."""
    v = np.array([[x, -half, -half], [x, half, -half], [x, half, half], [x, -half, half]])
    return trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]], process=False)


SMALL = Intrinsics.from_fov(64, 48, math.radians(60.0))


def test_a_wall_facing_the_camera_has_one_depth_and_its_points_lie_on_it() -> None:
    cam = DepthCamera(SMALL)
    frame = cam.frame(wall(2.5), looking_along_x((0.5, 0.0, 0.0)))
    np.testing.assert_allclose(frame.depth, 2.0, atol=1e-12)
    assert frame.points.shape == (64 * 48, 3)
    np.testing.assert_allclose(frame.points[:, 0], 2.5, atol=1e-12)


def test_pixels_reproject_to_their_own_pixel() -> None:
    cam = DepthCamera(Intrinsics(32, 24, 40.0, 50.0, 15.0, 12.5))
    z = np.linspace(0.5, 3.0, 32 * 24).reshape(24, 32)
    pts = cam.points(z)
    u = cam.intrinsics.fx * pts[:, 0] / pts[:, 2] + cam.intrinsics.cx
    v = cam.intrinsics.fy * pts[:, 1] / pts[:, 2] + cam.intrinsics.cy
    uu, vv = np.meshgrid(np.arange(32), np.arange(24))
    np.testing.assert_allclose(u, uu.ravel(), atol=1e-9)
    np.testing.assert_allclose(v, vv.ravel(), atol=1e-9)
    np.testing.assert_allclose(pts[:, 2], z.ravel())


def test_a_sphere_shows_its_near_side_and_hides_the_wall_behind_it() -> None:
    cam = DepthCamera(Intrinsics.from_fov(81, 61, math.radians(40.0)))
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=0.3)
    sphere.apply_translation([2.0, 0.0, 0.0])
    z = cam.depth([sphere, wall(4.0)], looking_along_x())
    centre = z[30, 40]  # the principal point's pixel looks along the axis
    assert centre == pytest.approx(1.7, abs=2e-3)  # the icosphere's facets sit inside
    # every pixel whose ray misses the sphere (by more than its facets) sees the wall
    rays = cam.intrinsics.rays()
    off_axis = np.linalg.norm(rays[:, :2], axis=1) / np.linalg.norm(rays, axis=1)
    miss = off_axis > math.sin(math.asin(0.3 / 2.0) + 0.01)
    hits = off_axis < math.sin(math.asin(0.3 / 2.0) - 0.01)
    np.testing.assert_allclose(z.ravel()[miss], 4.0, atol=1e-9)
    assert (z.ravel()[hits] < 2.0).all()


def test_range_limits_drop_returns_outside_them() -> None:
    cam = DepthCamera(SMALL, near=0.3, far=3.0)
    assert np.isnan(cam.depth(wall(3.5), looking_along_x())).all()
    assert np.isnan(cam.depth(wall(0.2), looking_along_x())).all()
    assert np.isfinite(cam.depth(wall(2.9), looking_along_x())).all()


def test_noise_grows_with_the_square_of_depth_and_dropout_removes_its_fraction() -> None:
    cam = DepthCamera(Intrinsics.from_fov(200, 150), noise=0.01, dropout=0.25)
    rng = np.random.default_rng(0)
    for depth in (1.0, 2.0):
        z = cam.measure(np.full(cam.shape, depth), rng)
        kept = z[np.isfinite(z)]
        # 30 000 pixels: the dropped fraction and the noise σ within a few sampling errors
        assert abs(1.0 - kept.size / z.size - 0.25) < 0.01
        assert kept.std() == pytest.approx(0.01 * depth**2, rel=0.03)
        assert abs(kept.mean() - depth) < 4 * 0.01 * depth**2 / math.sqrt(kept.size)


def test_bad_settings_are_input_errors() -> None:
    with pytest.raises(InputError, match="far"):
        DepthCamera(near=2.0, far=1.0)
    with pytest.raises(InputError, match="dropout"):
        DepthCamera(dropout=1.0)
    with pytest.raises(InputError, match="fx"):
        Intrinsics(fx=-1.0)
    with pytest.raises(InputError, match="rng"):
        DepthCamera(SMALL, noise=0.01).measure(np.ones((48, 64)))
    with pytest.raises(InputError, match="rotation"):
        DepthCamera(SMALL).depth(wall(2.0), np.diag([1.0, 1.0, -1.0, 1.0]))


def test_the_body_filter_drops_the_robot_and_keeps_its_shadow() -> None:
    """A sphere (the robot's own body) between the camera and a wall: with the sphere
    as ``body`` its pixels return nothing and it still hides the wall behind it."""
    cam = DepthCamera(Intrinsics.from_fov(81, 61, math.radians(40.0)))
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=0.3)
    sphere.apply_translation([2.0, 0.0, 0.0])
    seen = cam.frame([sphere, wall(4.0)], looking_along_x())
    filtered = cam.frame(wall(4.0), looking_along_x(), body=[sphere])
    on_sphere = np.isfinite(seen.depth) & (seen.depth < 3.0)
    assert on_sphere.sum() > 100
    assert filtered.body is not None
    np.testing.assert_array_equal(filtered.body, on_sphere)  # exactly the sphere's pixels
    assert np.isnan(filtered.depth[on_sphere]).all()  # gone, and no wall behind them
    np.testing.assert_array_equal(filtered.depth[~on_sphere], seen.depth[~on_sphere])
    np.testing.assert_allclose(filtered.points[:, 0], 4.0, atol=1e-12)  # only the wall
    assert len(filtered.points) == on_sphere.size - on_sphere.sum()


def test_first_hits_name_the_mesh_each_ray_hit() -> None:
    from reachwise.geometry.raycast import first_hits

    near, far = wall(1.0, half=0.5), wall(3.0)
    origins = np.zeros((3, 3))
    directions = np.array([[1.0, 0.0, 0.0], [1.0, 0.9, 0.0], [-1.0, 0.0, 0.0]])
    hit, dist, which = first_hits([near, far], origins, directions)
    np.testing.assert_array_equal(hit, [True, True, False])
    np.testing.assert_array_equal(which, [0, 1, -1])
    np.testing.assert_allclose(dist[:2], [1.0, 3.0 * math.hypot(1.0, 0.9)])


def test_pixel_spacing_is_the_distance_of_diagonal_neighbours() -> None:
    cam = DepthCamera(Intrinsics(32, 24, 40.0, 50.0, 15.0, 12.5))
    pts = cam.points(np.full(cam.shape, 2.0))
    diagonal = np.linalg.norm(pts[0] - pts[32 + 1])  # pixel (0, 0) and (1, 1)
    assert cam.pixel_spacing(2.0) == pytest.approx(diagonal)
