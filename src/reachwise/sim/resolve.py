"""The first stage of a run: a scenario *resolved*. :func:`resolve_scenario` reads and
validates every file a scenario names, once, into a frozen :class:`ResolvedScenario`:
the scenario itself, its robots, the clouds and solids of their links, the clouds of
the objects (and of their scheduled replacements), the surfaces the depth sensors see,
the scan scenes of scanned objects and the watched self-collision pairs.

The second stage, :func:`reachwise.sim.world.build_world`, makes the world from that
object alone (no file is opened, nothing from :mod:`reachwise.io` imported there); the
third, :func:`reachwise.sim.simulate.run_world`, runs the loop. A scan (the scanner's
ray casts, its noise and occlusion fill) is computed in the build and at each re-scan
from the resolved :class:`~reachwise.geometry.scan_scene.ScanScene`: it reads no file.

The resolver sits in ``sim`` rather than in ``io`` because the scenario schema it
resolves (:mod:`reachwise.sim.scenarios`) is a ``sim`` module and ``io`` sits below
``sim``.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError
from reachwise.geometry.cloud import PointCloud, sample_mesh_surface
from reachwise.io.clouds import load_cloud, load_mesh_cloud
from reachwise.io.meshes import load_mesh
from reachwise.io.robot_clouds import link_cloud, link_mesh, shape_meshes
from reachwise.kinematics.robot import Robot
from reachwise.sim.contact import Solid, solid_of_link, solid_of_mesh
from reachwise.sim.robots import robot_of
from reachwise.sim.scenario_inputs import check_requirements, scan_target, watched_self_pairs
from reachwise.sim.scenarios import ObjectSpec, RobotSpec, Scenario, load_scenario

if TYPE_CHECKING:
    import trimesh

    from reachwise.geometry.scan_scene import ScanScene

__all__ = ["ResolvedScenario", "Surface", "box_solid", "cloud_key", "resolve_scenario"]

#: A surface in its own frame: the mesh ``(vertices (V, 3), faces (F, 3))`` and its solid.
Surface = tuple[tuple[NDArray[np.float64], NDArray[np.int64]], Solid]


def cloud_key(obj: str, k: int | None = None) -> str:
    """The key of an object's cloud in :attr:`ResolvedScenario.object_clouds`: the
    object's name for its cloud at the start, ``name@k`` for its ``k``-th scheduled
    cloud (``clouds[k]``)."""
    return obj if k is None else f"{obj}@{k}"


def _mesh_links(robot: Robot) -> Mapping[str, trimesh.Trimesh]:
    """Every link of ``robot`` that has a mesh shape, as one mesh (its files read)."""
    return _frozen(
        {
            link: link_mesh(robot, link)
            for link, shapes in robot.geometry.items()
            if any(g.shape == "mesh" for g in shapes)
        }
    )


def _frozen(d: Mapping[str, Any]) -> Mapping[str, Any]:
    return MappingProxyType(dict(d))


@dataclass(frozen=True)
class ResolvedScenario:
    """A scenario with everything it reads from files already read and checked.

    - ``scenario`` — the validated scenario (its spec, name and source);
    - ``robots`` — robot name → the robot model, at the scenario's base pose;
    - ``link_clouds`` — ``robot/link`` → (cloud in the link frame, solid) of every link
      the scene carries;
    - ``link_surfaces`` — ``robot/link`` → :data:`Surface` of every link a sensor sees
      (empty when no sensor looks);
    - ``object_clouds`` — :func:`cloud_key` → the cloud of an object that is not
      scanned, at the start and at each scheduled change;
    - ``object_surfaces`` — object → ``((t, surface), …)``, the surface it has from
      time ``t`` on (for the sensors and the true clearance);
    - ``scan_targets`` — scanned object → what its scanner scans;
    - ``self_pairs`` — index of a ``watch: {self: …}`` entry → the link pairs it lists or
      picks (``pairs: auto``), or ``None`` for every non-adjacent pair;
    - ``self_margins`` — the same index → each of its pairs' margin (m, between the
      surfaces): the watch's, or a pair's own (``pairs: auto``, a structurally close
      pair, :mod:`reachwise.distance.self_pairs`);
    - ``link_meshes`` — robot name → link → its shapes as one mesh, for every link with a
      mesh shape (read from its file here; a MuJoCo plant takes its inertia from it).
    """

    scenario: Scenario
    robots: Mapping[str, Robot]
    link_clouds: Mapping[str, tuple[PointCloud, Solid]]
    link_surfaces: Mapping[str, Surface] = field(default_factory=dict)
    object_clouds: Mapping[str, PointCloud] = field(default_factory=dict)
    object_surfaces: Mapping[str, tuple[tuple[float, Surface], ...]] = field(default_factory=dict)
    scan_targets: Mapping[str, ScanScene] = field(default_factory=dict)
    self_pairs: Mapping[int, tuple[tuple[str, str], ...] | None] = field(default_factory=dict)
    self_margins: Mapping[int, Mapping[tuple[str, str], float]] = field(default_factory=dict)
    link_meshes: Mapping[str, Mapping[str, trimesh.Trimesh]] = field(default_factory=dict)


def resolve_scenario(scenario: Scenario | str | Path | ResolvedScenario) -> ResolvedScenario:
    """Read and check every input of ``scenario`` (a built-in name, a file or a
    ``Scenario``) once: see :class:`ResolvedScenario`. A ``ResolvedScenario`` is
    returned as it is. Errors name the scenario and the field."""
    if isinstance(scenario, ResolvedScenario):
        return scenario
    sc = load_scenario(scenario)
    check_requirements(sc)
    robots: dict[str, Robot] = {r.name: robot_of(r, sc) for r in sc.spec.robots}
    sc = _named_starts(sc, robots)
    links: dict[str, tuple[PointCloud, Solid]] = {}
    for rs in sc.spec.robots:
        robot = robots[rs.name]
        if len(rs.q0) != robot.n:
            raise InputError(sc.source, f"robots.{rs.name}.q0", f"expected {robot.n} values")
        chosen = rs.links if rs.links is not None else list(robot.geometry)
        _check_link_clouds(sc, rs, robot, chosen)
        for link in chosen:
            if link not in robot.body_names and link not in robot.link_names:
                where = f"robots.{rs.name}.links"
                raise unknown(sc.source, where, f"no link {link!r}", link, robot.body_names)
            links[f"{rs.name}/{link}"] = _link_cloud(sc, rs, robot, link, f"{rs.name}/{link}")
    clouds: dict[str, PointCloud] = {}
    targets: dict[str, ScanScene] = {}
    for os_ in sc.spec.objects:
        if os_.scanner is not None:
            try:
                targets[os_.name] = scan_target(os_.scanner, sc, os_.name)
            except InputError as exc:
                raise InputError(sc.source, f"objects.{os_.name}.scanner", str(exc)) from None
        elif os_.scene:
            clouds[cloud_key(os_.name)] = _object_cloud(os_, sc, os_.name, os_.seed)
        for k, c in enumerate(os_.clouds):
            clouds[cloud_key(os_.name, k)] = _object_cloud(c, sc, os_.name, os_.seed + k + 1)
    seen = bool(sc.spec.sensors) or not all(o.scene for o in sc.spec.objects)
    own = _self_pairs(sc, robots, links)
    return ResolvedScenario(
        scenario=sc,
        robots=_frozen(robots),
        link_clouds=_frozen(links),
        link_surfaces=_frozen(_link_surfaces(sc, robots) if seen else {}),
        object_clouds=_frozen(clouds),
        object_surfaces=_frozen(_object_surfaces(sc) if seen else {}),
        scan_targets=_frozen(targets),
        self_pairs=MappingProxyType({i: None if m is None else tuple(m) for i, m in own.items()}),
        self_margins=MappingProxyType(
            {i: MappingProxyType(m) for i, m in own.items() if m is not None}
        ),
        link_meshes=_frozen({name: _mesh_links(robot) for name, robot in robots.items()}),
    )


def _named_starts(sc: Scenario, robots: Mapping[str, Robot]) -> Scenario:
    """``sc`` with every named ``q0`` (``q0: ready``) replaced by the joint values of
    that ``group_state`` of the robot's SRDF (:mod:`reachwise.sim.srdf_inputs`); ``sc``
    itself when no start is named."""
    if all(not isinstance(rs.q0, str) for rs in sc.spec.robots):
        return sc
    from reachwise.io.ros.joint_state import robot_joint_names
    from reachwise.sim.srdf_inputs import named_pose, robot_srdf

    specs = []
    for rs in sc.spec.robots:
        if isinstance(rs.q0, str):
            where = f"robots.{rs.name}.q0"
            found = robot_srdf(sc, rs.name)
            if found is None:
                raise InputError(
                    sc.source, where,
                    f"{rs.q0!r} names a pose: give the robot's SRDF in a self watch "
                    f"(watch: [{{self: {{robot: {rs.name}, pairs: {{srdf: FILE}}}}, margin: …}}]) "
                    "or joint values",
                )  # fmt: skip
            robot = robots[rs.name]
            q = named_pose(found[0], rs.q0, robot, robot_joint_names(robot), sc.source, where)
            rs = rs.model_copy(update={"q0": q})
        specs.append(rs)
    named = Scenario(sc.spec.model_copy(update={"robots": specs}), sc.source, sc.folder)
    named.cache_dir = sc.cache_dir
    return named


def unknown(source: str, field: str, what: str, name: str, valid: Sequence[str]) -> InputError:
    """``what``, the valid names and the closest of them (an unknown link or cloud)."""
    close = difflib.get_close_matches(name, list(valid), n=1)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    return InputError(source, field, f"{what}; valid: {', '.join(valid)}{hint}")


def _check_link_clouds(sc: Scenario, rs: RobotSpec, robot: Robot, links: list[str]) -> None:
    """Each ``link_clouds`` entry names a link that is given a cloud: an entry that would
    never be used (a misspelt link, one outside ``links``) is an error."""
    for link in rs.link_clouds:
        where = f"robots.{rs.name}.link_clouds.{link}"
        if link not in robot.body_names and link not in robot.link_names:
            raise unknown(sc.source, where, f"no link {link!r}", link, robot.body_names)
        if link not in links:
            raise InputError(
                sc.source, where,
                f"{link!r} is not among the links given clouds ({', '.join(links)}); "
                "add it to links",
            )  # fmt: skip


def _link_mesh(sc: Scenario, rs: RobotSpec, link: str) -> trimesh.Trimesh:
    """The scenario's ``link_clouds`` mesh of ``link``, placed in the link frame;
    InputError naming the scenario field if it does not load."""
    over = rs.link_clouds[link]
    try:
        mesh = load_mesh(sc.path(over.mesh))
    except InputError as exc:
        where = f"robots.{rs.name}.link_clouds.{link}.mesh"
        raise InputError(sc.source, where, str(exc)) from None
    mesh.apply_transform(over.pose.matrix())
    return mesh


def _link_cloud(
    sc: Scenario, rs: RobotSpec, robot: Robot, link: str, obj: str
) -> tuple[PointCloud, Solid]:
    """The cloud of ``link`` (the scenario's ``link_clouds`` mesh, or the robot's own
    geometry) and its solid."""
    over = rs.link_clouds.get(link)
    if over is not None:
        mesh = _link_mesh(sc, rs, link)
        rng = np.random.default_rng([rs.seed, robot.link_index(link)])
        frame = robot.frame_of(link)
        cloud = sample_mesh_surface(
            mesh, n=over.points, seed=rng, frame=frame, name=obj,
            max_points=sc.spec.size_limits.max_points,
        )  # fmt: skip
        return cloud, solid_of_mesh(mesh)
    if link not in robot.geometry:
        raise InputError(sc.source, f"robots.{rs.name}.links", f"link {link!r} has no geometry")
    cloud = link_cloud(
        robot, link, rs.points, rs.seed, density=rs.density, resolution=rs.resolution
    )
    shapes = robot.geometry[link]
    has_mesh = any(g.shape == "mesh" for g in shapes)
    return cloud, solid_of_link(shapes, shape_meshes(robot, link) if has_mesh else None)


def _object_cloud(spec: Any, sc: Scenario, name: str, seed: int) -> PointCloud:
    """The cloud of an object spec that is not scanned (a ``box``, ``mesh`` or
    ``file``), or of one of its scheduled clouds."""
    where = f"objects.{name}"
    if spec.box is not None:
        import trimesh

        box = trimesh.creation.box(extents=spec.box)
        return sample_mesh_surface(
            box, n=spec.points, seed=seed, name=name, max_points=sc.spec.size_limits.max_points
        )
    try:
        if spec.mesh is not None:
            return load_mesh_cloud(
                sc.path(spec.mesh), spec.points, seed, name=name,
                max_points=sc.spec.size_limits.max_points,
            )  # fmt: skip
        return load_cloud(sc.path(spec.file), max_points=sc.spec.size_limits.max_cloud_points)
    except InputError as exc:
        raise InputError(sc.source, where, str(exc)) from None


def _surface(item: Any, sc: Scenario, where: str) -> Surface:
    """The mesh and solid of a ``mesh`` or ``box`` spec, in the object frame."""
    import trimesh

    if item.box is not None:
        mesh = trimesh.creation.box(extents=item.box)
        solid = Solid("box", np.eye(4), 0.5 * np.asarray(item.box, dtype=float))
    else:
        try:
            mesh = load_mesh(sc.path(item.mesh))
        except InputError as exc:
            raise InputError(sc.source, f"{where}.mesh", str(exc)) from None
        solid = solid_of_mesh(mesh)
    v = np.asarray(mesh.vertices, dtype=np.float64)
    f = np.asarray(mesh.faces, dtype=np.int64)
    return (v, f), solid


def _object_surfaces(sc: Scenario) -> dict[str, tuple[tuple[float, Surface], ...]]:
    """Each object's surface at the start and after each scheduled change that has one."""
    out = {}
    for os_ in sc.spec.objects:
        shapes: list[tuple[float, ObjectSpec | Any]] = [(0.0, os_)]
        shapes += [(c.t, c) for c in os_.clouds]
        found = tuple(
            (t, _surface(item, sc, f"objects.{os_.name}"))
            for t, item in shapes
            if item.mesh is not None or item.box is not None
        )
        if found:
            out[os_.name] = found
    return out


def _link_surfaces(sc: Scenario, robots: Mapping[str, Robot]) -> dict[str, Surface]:
    """Every link's collision surface in the link frame (the scenario's ``link_clouds``
    mesh, or the union of the robot's shapes of that link) and its solid."""
    import trimesh

    out = {}
    for rs in sc.spec.robots:
        robot = robots[rs.name]
        for link in robot.body_names:
            if link in rs.link_clouds:
                mesh = _link_mesh(sc, rs, link)
                solid = solid_of_mesh(mesh)
            elif link in robot.geometry:
                parts = shape_meshes(robot, link)
                solid = solid_of_link(robot.geometry[link], parts)
                joined = parts[0] if len(parts) == 1 else trimesh.util.concatenate(parts)
                if not isinstance(joined, trimesh.Trimesh):  # pragma: no cover - meshes join
                    where = f"robots.{rs.name}.links"
                    raise InputError(sc.source, where, f"{link}: shapes do not join")
                mesh = joined
            else:
                continue
            v = np.asarray(mesh.vertices, dtype=np.float64)
            out[f"{rs.name}/{link}"] = ((v, np.asarray(mesh.faces, dtype=np.int64)), solid)
    return out


def _self_pairs(
    sc: Scenario, robots: Mapping[str, Robot], links: Mapping[str, tuple[PointCloud, Solid]]
) -> dict[int, dict[tuple[str, str], float] | None]:
    """The link pairs of each ``self`` watch (listed, or picked for ``pairs: auto``),
    each with its margin."""
    out: dict[int, dict[tuple[str, str], float] | None] = {}
    for i, w in enumerate(sc.spec.watch):
        if w.self_ is None:
            continue
        rspec = next(x for x in sc.spec.robots if x.name == w.self_)
        prefix = f"{w.self_}/"
        clouds = {k[len(prefix) :]: c for k, (c, _) in links.items() if k.startswith(prefix)}
        for link in w.links or ():  # each a link with a cloud
            if link not in clouds:
                what = f"robot {w.self_!r} has no cloud on {link!r}"
                raise unknown(sc.source, f"watch[{i}].links", what, link, list(clouds))
        out[i] = watched_self_pairs(w, robots[w.self_], rspec, clouds, sc, f"watch[{i}]")
    return out


def box_solid(box: Any) -> Solid | None:
    """The solid of a ``box`` object (centred on its frame), for the contact check."""
    return None if box is None else Solid("box", np.eye(4), 0.5 * np.asarray(box, dtype=float))
