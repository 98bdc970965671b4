"""The simulator's own safety judges, judged: ``SimulationLog.limits_held`` /
``speeds_held`` / ``min_distance`` (with ``closest_pair`` and ``first_contact``) and
``Solid.depth`` on synthetic logs and analytic geometry with a known violation, speed
violation, penetration and near miss. Every "limits held, no collision" assertion of
the simulation tests trusts these; each must report exactly the planted fault, at its
tick, on its joint or pair, and nothing on a clean log.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from reachwise.distance import closest_points
from reachwise.sim.contact import Solid, solid_of_mesh
from reachwise.sim.log import SimulationLog
from reachwise.sim.scenarios import scenario_from_dict
from reachwise.sim.simulate import simulate

LOWER = np.array([-1.0, -2.0, 0.0])
UPPER = np.array([1.0, 2.0, 0.5])
VMAX = np.array([0.5, 1.0, 0.2])


def _log(
    q: dict[str, NDArray[np.float64]],
    *,
    qdot: dict[str, NDArray[np.float64]] | None = None,
    command: dict[str, NDArray[np.float64]] | None = None,
    signed: NDArray[np.float64] | None = None,
    pairs: tuple[str, ...] = (),
    lower: NDArray[np.float64] = LOWER,
    upper: NDArray[np.float64] = UPPER,
    vmax: NDArray[np.float64] = VMAX,
) -> SimulationLog:
    """A synthetic log: joint paths per robot, velocities (default 0), signed distances."""
    robots = tuple(q)
    T, n = next(iter(q.values())).shape
    zero = {r: np.zeros((T, n)) for r in robots}
    s = np.full((T, 0), np.inf) if signed is None else np.asarray(signed, dtype=float)
    return SimulationLog(
        scenario="synthetic",
        avoidance=True,
        dt=0.01,
        t=0.01 * np.arange(T),
        robots=robots,
        q={r: np.asarray(v, dtype=float) for r, v in q.items()},
        qdot=qdot or zero,
        command=command or zero,
        tool={r: np.broadcast_to(np.eye(4), (T, 4, 4)).copy() for r in robots},
        state={r: np.full(T, "moving") for r in robots},
        goal_index={r: np.zeros(T, dtype=np.int64) for r in robots},
        pairs=pairs,
        distance=np.where(s < 0, 0.0, s),
        signed=s,
        margins=np.full(len(pairs), 0.1),
        lower={r: lower for r in robots},
        upper={r: upper for r in robots},
        vmax={r: vmax for r in robots},
    )


def _inside_path(T: int = 8) -> NDArray[np.float64]:
    """A joint path strictly inside LOWER..UPPER, touching no limit."""
    u = np.linspace(0.0, 1.0, T)[:, None]
    return LOWER + (UPPER - LOWER) * (0.2 + 0.6 * u * np.array([1.0, 0.5, 0.25]))


def _where(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    return [(int(k), int(j)) for k, j in np.argwhere(mask)]


# ------------------------------------------------------------------ joint limits


def test_a_path_inside_its_limits_holds_even_on_the_limits() -> None:
    q = _inside_path()
    q[2] = UPPER  # exactly on every upper limit
    q[5] = LOWER  # exactly on every lower limit
    log = _log({"arm": q})
    assert log.limits_held() == {"arm": True}
    assert _where(log.limit_violations()["arm"]) == []


@pytest.mark.parametrize("side", ["upper", "lower"])
def test_a_joint_past_a_limit_is_reported_at_its_tick(side: str) -> None:
    q = _inside_path()
    if side == "upper":
        q[4, 1] = UPPER[1] + 1e-3
    else:
        q[4, 1] = LOWER[1] - 1e-3
    clean = _inside_path()
    log = _log({"arm": q, "other": clean})
    assert log.limits_held() == {"arm": False, "other": True}
    assert _where(log.limit_violations()["arm"]) == [(4, 1)]


def test_the_tolerance_is_the_only_slack() -> None:
    q = _inside_path()
    q[3, 0] = UPPER[0] + 0.5e-9
    assert _log({"arm": q}).limits_held() == {"arm": True}
    q[3, 0] = UPPER[0] + 2e-9
    assert _log({"arm": q}).limits_held() == {"arm": False}
    assert _log({"arm": q}).limits_held(tol=1e-8) == {"arm": True}


@settings(max_examples=60, deadline=None)
@given(
    k=st.integers(0, 11),
    j=st.integers(0, 2),
    excess=st.floats(1e-7, 10.0),
    upper=st.booleans(),
)
def test_any_single_excursion_is_found_exactly(k: int, j: int, excess: float, upper: bool) -> None:
    """A path inside its limits with one sample pushed out: exactly that sample is
    flagged, whether it is the first tick (a start outside that moves back in at once
    is allowed: then the next tick is not flagged either) or a later one."""
    q = _inside_path(12)
    q[k, j] = UPPER[j] + excess if upper else LOWER[j] - excess
    log = _log({"arm": q})
    expected = [] if k == 0 else [(k, j)]
    assert _where(log.limit_violations()["arm"]) == expected
    assert log.limits_held()["arm"] == (k == 0)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_joint_starting_outside_may_move_back_inward(sign: float) -> None:
    """Joint 0 starts 0.3 rad past its limit (above the upper one for sign +1, below
    the lower one for -1), approaches it in steps, waits, enters and stays inside."""
    q = _inside_path(9)
    edge = UPPER[0] if sign > 0 else LOWER[0]
    q[:, 0] = edge + sign * np.array([0.3, 0.2, 0.2, 0.1, 0.0, -0.1, -0.1, -0.2, -0.1])
    assert _log({"arm": q}).limits_held() == {"arm": True}


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_joint_starting_outside_must_not_move_farther_out(sign: float) -> None:
    q = _inside_path(6)
    edge = UPPER[0] if sign > 0 else LOWER[0]
    q[:, 0] = edge + sign * np.array([0.3, 0.2, 0.25, 0.1, 0.0, 0.0])
    log = _log({"arm": q})
    assert log.limits_held() == {"arm": False}
    assert _where(log.limit_violations()["arm"]) == [(2, 0)]  # 0.25 after 0.2


def test_a_joint_back_inside_must_stay_inside() -> None:
    q = _inside_path(6)
    q[:, 0] = UPPER[0] + np.array([0.3, 0.1, -0.1, 0.05, -0.2, -0.2])
    log = _log({"arm": q})
    assert _where(log.limit_violations()["arm"]) == [(3, 0)]  # out again after entering


def test_a_joint_starting_outside_and_standing_still_holds() -> None:
    q = _inside_path(5)
    q[:, 2] = UPPER[2] + 0.4  # the controller has no reason to move it: not farther out
    assert _log({"arm": q}).limits_held() == {"arm": True}


def test_a_log_without_ticks_holds() -> None:
    log = _log({"arm": np.zeros((0, 3))})
    assert log.limits_held() == {"arm": True} and log.speeds_held() == {"arm": True}


# ------------------------------------------------------------------ speeds


@pytest.mark.parametrize("which", ["command", "qdot"])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_speed_beyond_vmax_is_reported_at_its_tick(which: str, sign: float) -> None:
    q = _inside_path(7)
    v = np.tile(0.5 * VMAX, (7, 1))
    v[1] = VMAX  # exactly at the bound: allowed
    bad = v.copy()
    bad[5, 2] = sign * (VMAX[2] + 1e-4)
    ok = {"arm": v, "other": v}
    faulty = {"arm": bad, "other": v}
    log = _log(
        {"arm": q, "other": q},
        command=faulty if which == "command" else ok,
        qdot=faulty if which == "qdot" else ok,
    )
    assert log.speeds_held() == {"arm": False, "other": True}
    assert _where(log.speed_violations()["arm"]) == [(5, 2)]
    assert _log({"arm": q}, command={"arm": v}, qdot={"arm": -v}).speeds_held() == {"arm": True}


# ------------------------------------------------------------------ distances and contact


def _analytic_signed(t: NDArray[np.float64]) -> tuple[NDArray[np.float64], tuple[str, ...]]:
    """Signed distances of three analytic pairs moving in time (m; < 0: depth):

    - ``ball|floor``: a sphere (r = 0.3) whose centre sinks from 1.0 m to 0.2 m above a
      plane: ``h - r``, a penetration of 0.1 m at the end;
    - ``box|box``: two cubes (half sizes 0.2 and 0.3) whose centres approach along x:
      ``gap = |dx| - 0.5``, never below 0.004 m (the near miss);
    - ``pipe|pipe``: two capsules (r = 0.05) on skew lines: ``dist(axes) - 0.1``.
    """
    h = 1.0 - 0.8 * t / t[-1]
    ball = h - 0.3
    dx = 1.5 - 0.996 * np.minimum(t / t[-2], 1.0)
    box = np.abs(dx) - 0.5
    z = 0.6 - 0.3 * t / t[-1]  # skew lines x-axis and y-axis at height z: distance z
    pipe = z - 0.1
    return np.column_stack([ball, box, pipe]), ("ball|floor", "box|box", "pipe|pipe")


def test_min_distance_reports_the_near_miss_and_the_penetration() -> None:
    t = 0.01 * np.arange(50)
    signed, pairs = _analytic_signed(t)
    log = _log({"arm": np.tile(_inside_path(1), (50, 1))}, signed=signed, pairs=pairs)
    md = log.min_distance
    np.testing.assert_array_equal(md, signed.min(axis=1))
    # near miss: the boxes come within 4 mm at tick 48, the pair named, no contact then
    k = int(np.argmin(signed[:, 1]))
    assert k == 48 and math.isclose(signed[k, 1], 0.004, abs_tol=1e-12)
    # the ball reaches the floor when h = r: 1 - 0.8 t/T = 0.3 -> t/T = 0.875
    first = int(np.flatnonzero(signed[:, 0] <= 0.0)[0])
    assert first == math.ceil(0.875 * 49)
    contact = log.first_contact()
    assert contact is not None and contact == (t[first], "ball|floor")
    assert log.closest_pair[first] == "ball|floor"
    assert math.isclose(md[-1], -0.1, abs_tol=1e-12)  # the deepest: 0.1 m into the floor
    summary = log.summary()
    assert math.isclose(summary["min_distance"], -0.1, abs_tol=1e-12)
    assert math.isclose(summary["min_distance_by_pair"]["box|box"], 0.004, abs_tol=1e-12)
    # before the ball touches, the closest pair is whichever analytic figure is smallest
    for i in range(first):
        assert log.closest_pair[i] == pairs[int(np.argmin(signed[i]))]
        assert md[i] > 0.0


def test_a_near_miss_alone_is_no_contact() -> None:
    t = 0.01 * np.arange(50)
    signed, pairs = _analytic_signed(t)
    near = signed[:, 1:2]  # the boxes only: 4 mm apart at the closest
    log = _log({"arm": np.tile(_inside_path(1), (50, 1))}, signed=near, pairs=pairs[1:2])
    assert log.first_contact() is None
    assert log.min_distance.min() == near.min() > 0.0
    assert int(np.argmin(log.min_distance)) == 48


def test_a_touch_is_a_contact_and_pairs_beyond_range_are_unnamed() -> None:
    signed = np.array([[np.inf, np.inf], [0.5, np.inf], [0.2, 0.0], [-0.01, -0.02]])
    log = _log({"arm": np.tile(_inside_path(1), (4, 1))}, signed=signed, pairs=("a|b", "a|c"))
    assert list(log.closest_pair) == ["", "a|b", "a|c", "a|c"]
    assert log.first_contact() == (0.02, "a|c")  # touching (0.0) counts
    assert log.min_distance[0] == np.inf
    empty = _log({"arm": np.tile(_inside_path(1), (4, 1))})
    assert np.all(empty.min_distance == np.inf) and list(empty.closest_pair) == [""] * 4
    assert empty.first_contact() is None


# ------------------------------------------------------------------ Solid.depth


def _pose(rotvec: Any, xyz: Any) -> NDArray[np.float64]:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = xyz
    return T


POSES = [np.eye(4), _pose([0.3, -1.1, 0.7], [1.0, -2.0, 0.5]), _pose([np.pi, 0, 0], [0, 0, 3])]
ORIGIN = _pose([0.0, 0.0, np.pi / 2], [0.1, 0.2, -0.3])  # the solid in its part frame


def _placed(solid_local: NDArray[np.float64], pose: NDArray[np.float64]) -> NDArray[np.float64]:
    """Points given in the solid's own frame, in world (pose @ origin applied)."""
    T = pose @ ORIGIN
    return solid_local @ T[:3, :3].T + T[:3, 3]


@pytest.mark.parametrize("pose", POSES)
def test_box_depth_is_the_distance_to_the_nearest_face(pose: NDArray[np.float64]) -> None:
    box = Solid("box", ORIGIN, np.array([0.5, 0.3, 0.2]))
    cases = [
        ([0.0, 0.0, 0.0], 0.2),  # centre: the nearest faces are the z faces
        ([0.45, 0.0, 0.0], 0.05),  # 5 cm behind the +x face
        ([0.0, -0.25, 0.1], 0.05),  # 5 cm from -y, 10 cm from +z
    ]
    for local, depth in cases:
        got = box.depth(_placed(np.array([local]), pose), pose)
        assert math.isclose(got, depth, abs_tol=1e-12), (local, got)
    for outside in ([0.51, 0.0, 0.0], [0.0, 0.0, -0.21], [0.6, 0.4, 0.3]):
        assert box.depth(_placed(np.array([outside]), pose), pose) == -np.inf
    # several points: the deepest counts
    pts = _placed(np.array([[0.45, 0, 0], [0.6, 0, 0], [0.0, 0.2, 0.0]]), pose)
    assert math.isclose(box.depth(pts, pose), 0.1, abs_tol=1e-12)


def _fibonacci_sphere(n: int, r: float) -> NDArray[np.float64]:
    i = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * i / n)
    th = np.pi * (1 + 5**0.5) * i
    pts = np.column_stack([np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)])
    return r * np.vstack([pts, [[0, 0, 1.0], [0, 0, -1.0]]])  # with both poles


@pytest.mark.parametrize("h", [0.5, 0.3, 0.25, 0.1, -0.1])
def test_sphere_into_a_floor_slab_is_as_deep_as_it_sinks(h: float) -> None:
    """A ball (r = 0.3) with its centre ``h`` above a floor slab's top face: it
    penetrates ``r - h`` (the slab is 1 m thick and 8 m wide: no other face nearer)."""
    floor = Solid("box", np.eye(4), np.array([4.0, 4.0, 0.5]))
    pose = _pose([0, 0, 0.4], [2.0, 1.0, -0.5])  # top face at z = 0 in world
    ball = _fibonacci_sphere(400, 0.3) + np.array([2.3, 0.8, h])
    got = floor.depth(ball, pose)
    if h > 0.3:
        assert got == -np.inf
    else:
        assert math.isclose(got, 0.3 - h, abs_tol=1e-12)


@pytest.mark.parametrize("pose", POSES)
def test_box_into_box_is_as_deep_as_the_overlap(pose: NDArray[np.float64]) -> None:
    """A cube (half 0.2) whose surface grid includes its face centres, centred 0.6 m
    along x from a cube of half 0.5: the overlap along x is 0.1 m."""
    big = Solid("box", ORIGIN, np.full(3, 0.5))
    g = np.linspace(-0.2, 0.2, 9)
    U, V = (a.ravel() for a in np.meshgrid(g, g))
    faces = []
    for ax in range(3):
        o = [k for k in range(3) if k != ax]
        for side in (-0.2, 0.2):
            f = np.empty((U.size, 3))
            f[:, ax], f[:, o[0]], f[:, o[1]] = side, U, V
            faces.append(f)
    small = np.concatenate(faces)
    for dx, depth in ((0.6, 0.1), (0.65, 0.05), (0.69, 0.01)):
        got = big.depth(_placed(small + np.array([dx, 0, 0]), pose), pose)
        assert math.isclose(got, depth, abs_tol=1e-12), (dx, got)
    assert big.depth(_placed(small + np.array([0.71, 0, 0]), pose), pose) == -np.inf


@pytest.mark.parametrize("pose", POSES)
def test_cylinder_depth_is_radial_or_axial_whichever_is_nearer(pose: NDArray[np.float64]) -> None:
    cyl = Solid("cylinder", ORIGIN, np.array([0.0, 0.0, 0.5]), radius=0.2)
    s = np.sqrt(0.5)
    cases = [
        ([0.0, 0.0, 0.0], 0.2),
        ([0.15 * s, 0.15 * s, 0.0], 0.05),  # 5 cm inside the mantle
        ([0.0, 0.0, 0.45], 0.05),  # 5 cm inside the +z cap
        ([0.1, 0.0, -0.42], 0.08),  # the -z cap is nearer than the mantle
    ]
    for local, depth in cases:
        got = cyl.depth(_placed(np.array([local]), pose), pose)
        assert math.isclose(got, depth, abs_tol=1e-12), (local, got)
    for outside in ([0.15, 0.15, 0.0], [0.0, 0.0, 0.51], [0.0, 0.21, 0.0]):
        assert cyl.depth(_placed(np.array([outside]), pose), pose) == -np.inf


def test_capsule_near_miss_and_overlap_against_the_cylinder_solid() -> None:
    """Two capsules (r = 0.05) on skew axes ``z`` apart: the clouds' distance is the
    analytic ``z - 2r`` within sampling, and the cylinder solid of one finds the other's
    axis points inside exactly when the axes are closer than its radius."""
    rng = np.random.default_rng(4)
    r, half = 0.05, 0.4

    def capsule_cloud(axis: int, z: float) -> NDArray[np.float64]:
        n = 4000
        u = rng.uniform(-half, half, n)
        a = rng.uniform(0, 2 * np.pi, n)
        p = np.zeros((n, 3))
        o = next(k for k in range(2) if k != axis)
        p[:, axis], p[:, o], p[:, 2] = u, r * np.cos(a), r * np.sin(a) + z
        caps = _fibonacci_sphere(400, r)
        ends = [caps + np.eye(3)[axis] * e + [0, 0, z] for e in (-half, half)]
        return np.vstack([p, *ends])

    for z, expect in ((0.3, 0.2), (0.104, 0.004)):  # far, and a 4 mm near miss
        a, b = capsule_cloud(0, 0.0), capsule_cloud(1, z)
        d = closest_points(a, b).distance
        assert expect - 1e-9 <= d <= expect + 0.006, (z, d)
    # the x-axis capsule as a cylinder solid (axis z of the solid = world x)
    cyl = Solid("cylinder", _pose([0, np.pi / 2, 0], [0, 0, 0]), np.array([0, 0, half]), radius=r)
    axis_pts = np.column_stack([np.zeros(81), np.linspace(-half, half, 81), np.zeros(81)])
    for z, depth in ((0.03, 0.02), (0.04, 0.01), (0.06, -np.inf)):
        got = cyl.depth(axis_pts + np.array([0, 0, z]), np.eye(4))
        assert got == depth if depth == -np.inf else math.isclose(got, depth, abs_tol=1e-12)


def _tetrahedron() -> trimesh.Trimesh:
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    mesh = trimesh.Trimesh(v, [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], process=True)
    mesh.fix_normals()
    return mesh


@pytest.mark.parametrize("pose", POSES)
def test_convex_mesh_depth_is_the_nearest_face_plane(pose: NDArray[np.float64]) -> None:
    solid = solid_of_mesh(_tetrahedron(), ORIGIN)
    assert solid.kind == "convex"
    slant = lambda p: (1.0 - sum(p)) / np.sqrt(3.0)  # noqa: E731  distance to x+y+z=1
    cases = [([0.1, 0.1, 0.1], 0.1), ([0.2, 0.2, 0.5], slant([0.2, 0.2, 0.5]))]
    cases += [([0.3, 0.05, 0.2], 0.05)]
    for local, depth in cases:
        got = solid.depth(_placed(np.array([local]), pose), pose)
        assert math.isclose(got, depth, abs_tol=1e-12), (local, got, depth)
    for outside in ([-0.01, 0.2, 0.2], [0.4, 0.4, 0.4], [0.2, 0.2, -0.1]):
        assert solid.depth(_placed(np.array([outside]), pose), pose) == -np.inf


def test_touching_a_surface_counts_as_inside() -> None:
    """Points exactly on the surface (exact arithmetic: identity placement) are at
    depth 0, not outside: a touch is a contact."""
    eye = np.eye(4)
    box = Solid("box", eye, np.array([0.5, 0.25, 0.125]))
    assert box.depth(np.array([[0.5, 0.0, 0.0], [2.0, 0, 0]]), eye) == 0.0
    cyl = Solid("cylinder", eye, np.array([0.0, 0.0, 0.5]), radius=0.25)
    assert cyl.depth(np.array([[0.0, 0.25, 0.0]]), eye) == 0.0
    assert cyl.depth(np.array([[0.0, 0.0, -0.5]]), eye) == 0.0
    tet = solid_of_mesh(_tetrahedron())
    assert tet.depth(np.array([[0.0, 0.25, 0.25]]), eye) == 0.0


def test_non_convex_mesh_reports_containment() -> None:
    ring = trimesh.creation.annulus(r_min=0.5, r_max=1.0, height=0.4)
    solid = solid_of_mesh(ring, ORIGIN)
    assert solid.kind == "mesh"
    for pose in POSES:
        assert solid.depth(_placed(np.array([[0.75, 0.0, 0.0]]), pose), pose) == 0.0
        assert solid.depth(_placed(np.array([[0.0, 0.0, 0.0]]), pose), pose) == -np.inf
        assert solid.depth(_placed(np.array([[0.0, -0.6, 0.3]]), pose), pose) == -np.inf
        both = _placed(np.array([[0.0, 0.0, 0.0], [0.0, -0.8, 0.1]]), pose)
        assert solid.depth(both, pose) == 0.0


# ------------------------------------------------------------------ the simulator itself


SLIDER = {
    "name": "slider",
    "convention": "modified",
    "joints": [{"type": "prismatic", "a": 0.0, "alpha": 0.0, "d": 0.0, "theta": 0.0,
                "limits": [0.0, 2.0], "vmax": 0.5}],
    "base": {"xyz": [0, 0, 0], "rpy": [0, 0, 0]},
    "tool": {"xyz": [0, 0, 0.1], "rpy": [0, 0, 0]},
    "geometry": {"link_1": {"box": [0.2, 0.2, 0.2], "points": 800}},
}  # fmt: skip
WALL_Z = 1.0


def _wall_run(tmp_path: Path) -> SimulationLog:
    """A 20 cm cube on a vertical slide driven (no avoidance) through a horizontal wall
    of points at z = 1 m (a 2 cm grid with a point on the slide's axis)."""
    (tmp_path / "slider.yaml").write_text(yaml.safe_dump(SLIDER))
    g = np.linspace(-0.3, 0.3, 31)
    X, Y = np.meshgrid(g, g)
    np.save(tmp_path / "wall.npy", np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, WALL_Z)]))
    data = {
        "name": "wall", "dt": 0.01, "duration": 8.0,
        "robots": [{"name": "s", "robot": "slider.yaml", "q0": [0.5], "links": ["link_1"],
                    "controller": {"v_max": 0.3}, "plant": {"kind": "kinematic"},
                    "goals": [{"name": "through", "xyz": [0.0, 0.0, 1.6], "dims": 3}]}],
        "objects": [{"name": "wall", "file": "wall.npy"}],
        "watch": [{"robot": "s", "environment": ["wall"], "margin": 0.2}],
    }  # fmt: skip
    return simulate(scenario_from_dict(data, "wall.yaml", tmp_path), avoidance=False)


def test_the_simulator_logs_the_analytic_gap_and_depth_of_a_box_through_a_wall(
    tmp_path: Path,
) -> None:
    log = _wall_run(tmp_path)
    q = log.q["s"][:, 0]
    assert q[0] == 0.5 and q.max() > 1.2  # it went all the way through
    top, bottom = q + 0.1, q - 0.1
    overlap = (top >= WALL_Z) & (bottom <= WALL_Z)
    depth = np.minimum(0.1, np.minimum(top - WALL_Z, WALL_Z - bottom))  # from the axis point
    s = log.signed[:, 0]
    np.testing.assert_allclose(s[overlap], -depth[overlap], atol=1e-12)
    gap = WALL_Z - top  # approaching: the cube's top face is the nearest surface
    before = ~overlap & (top < WALL_Z) & np.isfinite(s)
    assert before.sum() > 10
    # surface samples: at least the gap, at most the gap with half a 2 cm grid cell aside
    assert np.all(s[before] >= gap[before] - 1e-12)
    assert np.all(s[before] <= np.hypot(gap[before], 0.02))
    first = int(np.flatnonzero(overlap)[0])
    assert log.first_collision == log.t[first] and log.first_collision_pair == log.pairs[0]
    assert log.first_contact() == (log.t[first], log.pairs[0])
    k = int(np.argmax(depth * overlap))
    assert math.isclose(log.min_distance.min(), -depth[k], abs_tol=1e-12)
    assert log.limits_held() == {"s": True} and log.speeds_held() == {"s": True}
