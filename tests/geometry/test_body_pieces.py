"""A body's 26-DOP pieces: a piece holds its points and its box holds the piece, the
points near a placed piece are those a brute-force test finds (the planes' largest
signed distance), and the pixels of a depth image that see a placed cube are the
cube's pixels of the rendering."""

from __future__ import annotations

import numpy as np
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from reachwise.geometry.body_pieces import (
    DOP26,
    body_pixels,
    cloud_piece,
    dop_bounds,
    near_pieces,
)
from reachwise.geometry.depth_camera import DepthCamera, Intrinsics


def _pose(seed: int) -> NDArray[np.float64]:
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    T = np.eye(4)
    T[:3, :3] = Q * np.sign(np.linalg.det(Q))
    T[:3, 3] = rng.uniform(-1.0, 1.0, 3)
    return T


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1), st.floats(0.0, 0.1))
def test_a_placed_piece_holds_its_points_and_its_box_holds_them(seed: int, reach: float) -> None:
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(int(rng.integers(1, 40)), 3)) * rng.uniform(0.01, 0.5, 3)
    T = _pose(seed + 1)
    piece = cloud_piece("arm", 1, pts)
    placed = piece.placed(T)
    world = pts @ T[:3, :3].T + T[:3, 3]
    assert near_pieces(world, [placed], 1e-12).all()  # on its planes, to rounding
    lo, hi = dop_bounds(piece.offsets, T)
    assert np.all(world >= lo - 1e-12) and np.all(world <= hi + 1e-12)
    # brute force: the largest signed distance to the planes against the reach
    probe = world.mean(axis=0) + rng.normal(size=(200, 3)) * 0.5
    gap = (probe @ placed[:, :3].T - placed[:, 3]).max(axis=1)
    assert np.array_equal(near_pieces(probe, [placed], reach), gap <= reach)
    assert np.allclose(np.linalg.norm(placed[:, :3], axis=1), 1.0)
    assert len(placed) == len(DOP26)


def test_the_pixels_that_see_a_placed_cube_are_the_cubes_pixels() -> None:
    cam = DepthCamera(Intrinsics(width=64, height=48, fx=60.0, fy=60.0, cx=31.5, cy=23.5))
    T = _pose(7)
    T[:3, 3] = [0.1, -0.05, 1.5]
    cube = trimesh.creation.box(extents=(0.3, 0.2, 0.25), transform=T)
    wall = trimesh.creation.box(extents=(6.0, 6.0, 0.05), transform=_at(2.4))
    depth = cam.depth([cube, wall], np.eye(4))
    alone = cam.depth([cube], np.eye(4))
    corners = np.array(cube.vertices) @ T[:3, :3]  # back in the cube's frame
    corners -= T[:3, 3] @ T[:3, :3]
    piece = cloud_piece("arm", 1, corners)
    mask = body_pixels(depth, (60.0, 60.0, 31.5, 23.5), np.eye(4), [piece.placed(T)], 0.02,
                       dop_bounds(piece.offsets, T))  # fmt: skip
    assert np.array_equal(mask, np.isfinite(alone))  # the wall is 0.5 m behind
    assert mask.any() and not mask.all()
    empty = body_pixels(depth, (60.0, 60.0, 31.5, 23.5), np.eye(4), [], 0.02,
                        dop_bounds(piece.offsets, T))  # fmt: skip
    assert not empty.any()


def _at(z: float) -> NDArray[np.float64]:
    T = np.eye(4)
    T[2, 3] = z
    return T
