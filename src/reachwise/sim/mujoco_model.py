"""A MuJoCo model of a reachwise robot for simulating its dynamics, built with ``mujoco.MjSpec``.

One body per frame of the DH chain: ``link_0`` is welded to the world at the robot's
base pose, ``link_i`` (i = 1 … N) is the child of ``link_{i-1}``. Its body frame *is*
reachwise's frame ``i``, so after ``mj_kinematics`` the body poses equal
``Robot.fk_all`` and the ``tool`` site equals ``Robot.fk``:

- modified DH (thesis P-I Eq. 2–3, Craig), ``T_i = Rx(α) Tx(a) Rz(θ) Tz(d)``: the body
  sits at ``Rx(α) Tx(a) Rz(θ) Tz(d)`` (the offsets) in its parent and the joint acts at
  the body origin about (hinge) or along (slide) the body's z axis — a rotation about z
  commutes with ``Tz(d)``, so ``Rz(θ) Tz(d) Rz(q) = Rz(θ + q) Tz(d)``;
- classic DH, ``T_i = Rz(θ) Tz(d) Tx(a) Rx(α)`` with the joint about z of the *parent*
  frame: the body sits at ``M = Rz(θ) Tz(d) Tx(a) Rx(α)`` and the joint axis and anchor
  are the parent's z axis and origin expressed in the body, ``Mᵀ e_z`` and ``−Rᵀ p``,
  because ``Rz(q) M = M (M⁻¹ Rz(q) M)``;
- a fixed row is a body without a joint; the tool frame is a site on the last body.

Joint ranges are the robot's limits in radians (metres for prismatic joints; a joint
without finite limits is unlimited). Every actuated joint gets a velocity servo —
MuJoCo's ``<velocity>`` actuator: gain ``kv`` (fixed), bias ``−kv q̇`` (affine), so its
force is ``kv (u − q̇)`` — with ``ctrlrange = ±v_max`` (commands beyond are
saturated); passive joints get no actuator, only viscous ``damping`` (they swing under
gravity). Link inertias come from the link geometry at a uniform ``density``
(boxes and cylinders as MuJoCo geoms, meshes by their convex hull via trimesh), with
``min_mass`` / ``min_inertia`` as lower bounds (links without geometry get exactly
those). Contacts are disabled (geoms do not collide and the contact stage is off):
collisions are what the reachwise distance scene checks, not MuJoCo.

MuJoCo is the optional ``sim`` extra: it is imported here only when a model is built.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import InputError, MissingDependency
from reachwise.kinematics.robot import Robot
from reachwise.kinematics.transforms import Pose, rot_x, rot_z, translation

__all__ = ["MujocoRobot", "dh_body_transform", "mujoco_model", "require_mujoco"]

#: What the MuJoCo plant needs and where it comes from (the optional extra).
_NEEDED = ("mujoco", "sim", "the MuJoCo plant")
#: The install hint, as :class:`~reachwise.errors.MissingDependency` words it.
MISSING = str(MissingDependency(*_NEEDED))


def require_mujoco() -> Any:
    """The ``mujoco`` module, or a :class:`~reachwise.errors.MissingDependency` naming
    the ``sim`` extra."""
    try:
        import mujoco
    except ImportError:
        raise MissingDependency(*_NEEDED) from None
    return mujoco


def dh_body_transform(classic: bool, a: float, alpha: float, d: float, theta: float) -> Pose:
    """The fixed part of one DH row, ``Rx(α) Tx(a) Rz(θ) Tz(d)`` (modified) or
    ``Rz(θ) Tz(d) Tx(a) Rx(α)`` (classic), with ``θ``, ``d`` the offsets (P-I Eq. 2)."""
    if classic:
        return rot_z(theta) @ translation(z=d) @ translation(x=a) @ rot_x(alpha)
    return rot_x(alpha) @ translation(x=a) @ rot_z(theta) @ translation(z=d)


@dataclass(frozen=True, eq=False)
class MujocoRobot:
    """A compiled MuJoCo model of ``robot`` and where each reachwise quantity lives in it.

    ``body`` holds the body id of ``link_0`` … ``link_N``; ``site`` the tool site;
    ``qpos`` / ``dof`` the address of each entry of reachwise's ``q`` (base to tool);
    ``actuator`` the velocity servo of each entry (``-1`` for a passive joint).
    """

    robot: Robot
    spec: Any  # mujoco.MjSpec
    model: Any  # mujoco.MjModel
    body: NDArray[np.int64]
    site: int
    qpos: NDArray[np.int64]
    dof: NDArray[np.int64]
    actuator: NDArray[np.int64]

    def frames(self, q: ArrayLike, data: Any = None) -> NDArray[np.float64]:
        """World pose of every frame, ``(N+2, 4, 4)`` in ``Robot.link_names`` order, from
        MuJoCo's ``mj_kinematics`` at joint values ``q`` (the rows of ``Robot.fk_all``)."""
        mujoco = require_mujoco()
        qq = np.asarray(q, dtype=float)
        if qq.shape != (self.robot.n,) or not np.isfinite(qq).all():
            raise InputError(self.robot.name, "q", f"expected {self.robot.n} finite values")
        d = mujoco.MjData(self.model) if data is None else data
        d.qpos[self.qpos] = qq
        mujoco.mj_kinematics(self.model, d)
        F = np.zeros((self.body.size + 1, 4, 4))
        F[:, 3, 3] = 1.0
        F[:-1, :3, :3] = d.xmat[self.body].reshape(-1, 3, 3)
        F[:-1, :3, 3] = d.xpos[self.body]
        F[-1, :3, :3] = d.site_xmat[self.site].reshape(3, 3)
        F[-1, :3, 3] = d.site_xpos[self.site]
        return F


def _quat(mujoco: Any, T: Pose) -> NDArray[np.float64]:
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(T[:3, :3]).ravel())
    return q


def _mesh_inertia(
    robot: Robot, links: list[str], density: float, meshes: Mapping[str, Any] | None
) -> Any:
    """Mass, centre and inertia (at the centre, frame coordinates) of the convex hull of
    the shapes of ``links`` (the bodies riding on one frame): each link's mesh from
    ``meshes`` (read already), else made from its shapes (a mesh file read here)."""
    import trimesh

    from reachwise.io.robot_clouds import link_mesh

    given = meshes or {}
    parts = [given[link] if link in given else link_mesh(robot, link) for link in links]
    joined = parts[0] if len(parts) == 1 else trimesh.util.concatenate(parts)
    hull = joined.convex_hull  # type: ignore[union-attr]
    hull.density = density
    return float(hull.mass), np.asarray(hull.center_mass), np.asarray(hull.moment_inertia)


def mujoco_model(
    robot: Robot,
    *,
    kv: float | ArrayLike = 1.0,
    force_limit: float | ArrayLike = math.inf,
    passive_damping: float | ArrayLike = 0.0,
    density: float = 1000.0,
    min_mass: float = 0.1,
    min_inertia: float = 1e-4,
    timestep: float = 0.001,
    gravity: bool = True,
    meshes: Mapping[str, Any] | None = None,
) -> MujocoRobot:
    """Build and compile the MuJoCo model of ``robot`` (see the module docstring).

    ``kv`` (N·s/rad or N·s/m) and ``force_limit`` (N·m or N, ``inf`` = none) per actuated
    joint or one value for all; ``passive_damping`` (N·m·s/rad) per passive joint or one
    value; ``density`` (kg/m³) of the link geometry; ``timestep`` (s) of the integrator
    (``implicitfast``, which treats the servo's velocity feedback implicitly, so a
    stiff servo stays stable); ``meshes``: link → its shapes as one mesh
    (:func:`reachwise.io.robot_clouds.link_mesh`), read already, as a resolved
    scenario holds them (``ResolvedScenario.link_meshes``); a link with a mesh shape
    not among them is read from its file (relative to the robot file's folder).
    """
    mujoco = require_mujoco()
    src = robot.source or robot.name
    act = np.asarray(robot.actuated, dtype=bool)
    n_act, n_pas = int(act.sum()), int((~act).sum())

    def per(value: float | ArrayLike, count: int, field: str, lo: float) -> NDArray[np.float64]:
        v = np.broadcast_to(np.asarray(value, dtype=float), (count,)) if count else np.empty(0)
        if np.isnan(v).any() or (v < lo).any():
            raise InputError(src, field, f"must be >= {lo}, got {value!r}")
        return np.array(v, dtype=float)

    kv_a = per(kv, n_act, "kv", 0.0)
    flim = per(force_limit, n_act, "force_limit", 0.0)
    damp = per(passive_damping, n_pas, "passive_damping", 0.0)
    if not (kv_a > 0).all():
        raise InputError(src, "kv", "servo gains must be > 0")
    for name, v in (("density", density), ("min_mass", min_mass), ("timestep", timestep)):
        if not (math.isfinite(v) and v > 0):
            raise InputError(src, name, f"must be a finite value > 0, got {v}")
    if not (math.isfinite(min_inertia) and min_inertia >= 0):
        raise InputError(src, "min_inertia", f"must be >= 0, got {min_inertia}")
    spec = _new_spec(mujoco, robot.name, (min_mass, min_inertia), timestep, gravity)
    bodies, joint_names = _bodies(mujoco, spec, robot, damp)
    T_tool = np.asarray(robot.tool)
    bodies[-1].add_site(name="tool", pos=T_tool[:3, 3], quat=_quat(mujoco, T_tool))
    _mass_properties(mujoco, robot, bodies, (density, min_mass), meshes)
    _actuators(mujoco, spec, robot, joint_names, kv_a, flim)

    try:
        model = spec.compile()
    except ValueError as exc:
        raise InputError(src, "mujoco", f"the MuJoCo model does not compile: {exc}") from None
    return _compiled(robot, spec, model, len(bodies), joint_names)


def _new_spec(
    mujoco: Any, name: str, bounds: tuple[float, float], timestep: float, gravity: bool
) -> Any:
    """An empty ``MjSpec`` named ``name``: angles in radians, mass and inertia bounded
    below by ``bounds`` (kg, kg·m²), the ``implicitfast`` integrator at ``timestep``
    (s), gravity along −z (or none) and no contacts."""
    spec = mujoco.MjSpec()
    spec.modelname = name
    spec.compiler.degree = False
    spec.compiler.boundmass, spec.compiler.boundinertia = bounds
    spec.option.timestep = timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.gravity = [0.0, 0.0, -9.81 if gravity else 0.0]
    spec.option.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    return spec


def _compiled(
    robot: Robot, spec: Any, model: Any, n_bodies: int, joint_names: list[str]
) -> MujocoRobot:
    """The compiled ``model`` with the indices of its bodies (``link_i``), tool site,
    joints' positions and velocities and the actuated joints' actuators (−1 for a
    passive joint)."""
    act = np.asarray(robot.actuated, dtype=bool)
    body_ids = np.array([model.body(f"link_{i}").id for i in range(n_bodies)], dtype=np.int64)
    jids = [model.joint(nm).id for nm in joint_names]
    actuator_ids = np.full(robot.n, -1, dtype=np.int64)
    for k, name in enumerate(joint_names):
        if act[k]:
            actuator_ids[k] = model.actuator(name).id
    return MujocoRobot(
        robot=robot,
        spec=spec,
        model=model,
        body=body_ids,
        site=int(model.site("tool").id),
        qpos=np.array([model.jnt_qposadr[j] for j in jids], dtype=np.int64),
        dof=np.array([model.jnt_dofadr[j] for j in jids], dtype=np.int64),
        actuator=actuator_ids,
    )


def _bodies(
    mujoco: Any, spec: Any, robot: Robot, damp: NDArray[np.float64]
) -> tuple[list[Any], list[str]]:
    """The chain of bodies ``link_0 … link_n`` (each placed by its DH transform) with
    a hinge or slide joint on every movable joint (passive ones damped by ``damp``),
    and the joints' names."""
    act = np.asarray(robot.actuated, dtype=bool)
    classic = robot.convention == "classic"
    bodies = [
        spec.worldbody.add_body(
            name="link_0", pos=robot.base[:3, 3], quat=_quat(mujoco, np.asarray(robot.base))
        )
    ]
    joint_names: list[str] = []
    used: set[str] = set()
    k = 0  # index into q
    for i, j in enumerate(robot.joints):
        M = dh_body_transform(classic, j.a, j.alpha, j.d, j.theta)
        body = bodies[-1].add_body(name=f"link_{i + 1}", pos=M[:3, 3], quat=_quat(mujoco, M))
        bodies.append(body)
        if j.movable:
            R, p = M[:3, :3], M[:3, 3]
            axis, anchor = (R.T[:, 2], -R.T @ p) if classic else (np.eye(3)[2], np.zeros(3))
            name = j.name if j.name and j.name not in used else f"q{k + 1}"
            used.add(name)
            lo, hi = j.limits
            limited = math.isfinite(lo) and math.isfinite(hi)
            body.add_joint(
                name=name,
                type=mujoco.mjtJoint.mjJNT_HINGE
                if j.type == "revolute"
                else mujoco.mjtJoint.mjJNT_SLIDE,
                axis=axis,
                pos=anchor,
                limited=mujoco.mjtLimited.mjLIMITED_TRUE
                if limited
                else mujoco.mjtLimited.mjLIMITED_FALSE,
                range=[lo, hi] if limited else [0.0, 0.0],
                damping=float(damp[int((~act[:k]).sum())]) if j.passive else 0.0,
            )
            joint_names.append(name)
            k += 1
    return bodies, joint_names


def _mass_properties(
    mujoco: Any, robot: Robot, bodies: list[Any], density_min_mass: tuple[float, float],
    meshes: Mapping[str, Any] | None,
) -> None:  # fmt: skip
    """Each frame's bodies' mass: the convex hull of their shapes when one is a mesh
    (an explicit inertia, at least ``min_mass``), else their primitive shapes as
    geoms of ``density`` (kg/m³)."""
    density, min_mass = density_min_mass
    src = robot.source or robot.name
    T_tool = np.asarray(robot.tool)
    on_frame: dict[str, list[str]] = {}
    for link in robot.geometry:
        on_frame.setdefault(robot.frame_of(link), []).append(link)
    tool_row = len(robot.link_names) - 1
    for frame, links in on_frame.items():
        idx = robot.link_index(frame)
        body = bodies[min(idx, len(bodies) - 1)]
        shapes = tuple(g for link in links for g in robot.geometry[link])
        link = frame
        if any(g.shape == "mesh" for g in shapes):
            # a mesh among the shapes: the convex hull of all of them gives the mass
            # properties, as the body's explicit inertia
            if idx == tool_row:
                raise InputError(src, f"geometry.{links[0]}",
                                 "a mesh on the tool frame is not supported")  # fmt: skip
            mass, com, inertia = _mesh_inertia(robot, links, density, meshes)
            body.explicitinertial = True
            body.mass = max(mass, min_mass)
            body.ipos = com
            body.fullinertia = [
                inertia[0, 0],
                inertia[1, 1],
                inertia[2, 2],
                inertia[0, 1],
                inertia[0, 2],
                inertia[1, 2],
            ]
            continue
        for i, g in enumerate(shapes):
            G = (T_tool if idx == tool_row else np.eye(4)) @ g.origin_matrix
            if g.shape == "box":
                gtype, size = mujoco.mjtGeom.mjGEOM_BOX, [s / 2 for s in (g.size or (0, 0, 0))]
            elif g.shape == "sphere":
                gtype, size = mujoco.mjtGeom.mjGEOM_SPHERE, [g.radius or 0.0, 0.0, 0.0]
            else:
                kind = mujoco.mjtGeom.mjGEOM_CAPSULE if g.shape == "capsule" else None
                gtype = kind if kind is not None else mujoco.mjtGeom.mjGEOM_CYLINDER
                size = [g.radius or 0.0, (g.length or 0.0) / 2, 0.0]
            body.add_geom(
                name=f"{link}_geom" if len(shapes) == 1 else f"{link}_geom_{i}",
                type=gtype,
                size=size,
                pos=G[:3, 3],
                quat=_quat(mujoco, G),
                density=density,
                contype=0,
                conaffinity=0,
            )


def _actuators(
    mujoco: Any, spec: Any, robot: Robot, joint_names: list[str], kv_a: NDArray[np.float64],
    flim: NDArray[np.float64],
) -> None:  # fmt: skip
    """A velocity servo on every actuated joint: gain ``kv_a`` (N·s/rad or N·s/m),
    its command limited to the joint's vmax and its force to ``flim`` (N·m or N)."""
    act = np.asarray(robot.actuated, dtype=bool)
    a = 0
    for k, name in enumerate(joint_names):
        if not act[k]:
            continue
        vmax = float(robot.vmax[k])
        actuator = spec.add_actuator(
            name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT, gear=[1, 0, 0, 0, 0, 0]
        )
        actuator.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        actuator.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        gain = np.zeros(10)
        gain[0] = kv_a[a]
        bias = np.zeros(10)
        bias[2] = -kv_a[a]
        actuator.gainprm = gain
        actuator.biasprm = bias
        if math.isfinite(vmax):
            actuator.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            actuator.ctrlrange = [-vmax, vmax]
        else:
            actuator.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        if math.isfinite(flim[a]):
            actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            actuator.forcerange = [-flim[a], flim[a]]
        else:
            actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_FALSE
        a += 1
