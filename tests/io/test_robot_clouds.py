"""Link clouds from robot geometry."""

from __future__ import annotations

import numpy as np
import pytest

import reachwise
from reachwise.errors import InputError
from reachwise.io.robot_clouds import link_cloud, link_clouds, link_mesh


def test_link_clouds_are_seeded_on_the_surface_in_link_frames() -> None:
    r = reachwise.load_robot("hiab-xs033")
    a = link_clouds(r, seed=3)
    b = link_clouds(r, seed=3)
    assert list(a) == [n for n in r.link_names if n in r.geometry]
    for k in a:
        np.testing.assert_array_equal(a[k].points, b[k].points)
        assert len(a[k]) == r.geometry[k][0].points and a[k].frame == k
    # box of the grabber: every point on its surface (one coordinate at a face)
    (g,) = r.geometry["link_6"]
    half = np.asarray(g.size) / 2
    x = a["link_6"].points - g.origin_matrix[:3, 3]
    on_face = np.isclose(np.abs(x), half, atol=1e-9).any(axis=1)
    assert on_face.all() and np.all(np.abs(x) <= half + 1e-9)
    # cylinder column: radius or caps
    c = link_cloud(r, "link_1", points=500)
    x = c.points - r.geometry["link_1"][0].origin_matrix[:3, 3]
    rad = np.hypot(x[:, 0], x[:, 1])
    assert np.all(rad <= 0.15 + 1e-9)
    assert link_cloud(r, "link_6", points=50, seed=1).points.shape == (50, 3)
    assert not np.array_equal(link_cloud(r, "link_6", seed=1).points, a["link_6"].points)


def test_mesh_geometry_relative_to_robot_file(tmp_path) -> None:  # type: ignore[no-untyped-def]
    import trimesh

    trimesh.creation.box(extents=(0.2, 0.2, 0.2)).export(tmp_path / "part.stl")
    (tmp_path / "r.yaml").write_text(
        "name: r\njoints:\n  - {type: revolute, a: 0, alpha: 0, d: 0, theta: 0}\n"
        "geometry: {link_1: {mesh: part.stl, points: 100, xyz: [1, 0, 0]}}\n"
    )
    r = reachwise.load_robot(tmp_path / "r.yaml")
    c = link_cloud(r, "link_1")
    assert len(c) == 100 and np.allclose(c.points.mean(axis=0), [1, 0, 0], atol=0.05)
    assert link_mesh(r, "link_1").is_watertight
    with pytest.raises(InputError, match="no geometry"):
        link_cloud(r, "link_0")
