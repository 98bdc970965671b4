"""A scenario's MoveIt SRDF: its disabled pairs as a self watch's pair rule, its named
poses as a robot's start.

``watch: [{self: {robot: arm, pairs: {srdf: arm.srdf}}, margin: 0.05}]`` watches every
pair of the robot's link clouds (restricted to the watch's ``links``) that the SRDF does
not disable with a ``<disable_collisions>`` — MoveIt's own rule: it checks every pair
it is not told to skip. A link the SRDF names must be a link of the robot's URDF (a
misspelt name is an error listing the valid ones and the closest); pairs naming a URDF
link that carries no cloud in the scene have nothing to watch and are left out.

``q0: ready`` (a name instead of joint values) is the SRDF's ``<group_state
name="ready">``: one value per movable joint of the robot, by URDF joint name (the
state's other joints, a gripper's fingers say, are not the robot's and are ignored).
The SRDF is the one a ``self`` watch of that robot names.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from reachwise.errors import InputError, UnknownName
from reachwise.io.srdf import Srdf, read_srdf
from reachwise.io.xml_tree import read_xml
from reachwise.kinematics.robot import Robot
from reachwise.sim.scenarios import Scenario, SrdfPairsSpec

if TYPE_CHECKING:
    from reachwise.geometry.cloud import PointCloud

__all__ = ["named_pose", "robot_srdf", "srdf_of", "srdf_watched_pairs"]


def srdf_of(sc: Scenario, pairs: SrdfPairsSpec, where: str) -> Srdf:
    """The SRDF a ``pairs: {srdf: FILE}`` names (relative to the scenario); its
    errors name the scenario field as well."""
    try:
        return read_srdf(sc.path(pairs.srdf))
    except InputError as exc:
        raise InputError(sc.source, f"{where}.pairs.srdf", str(exc)) from None


def robot_srdf(sc: Scenario, robot: str) -> tuple[Srdf, str] | None:
    """The SRDF the first ``self`` watch of ``robot`` names, with that watch's field,
    or None."""
    for i, w in enumerate(sc.spec.watch):
        if w.self_ == robot and isinstance(w.pairs, SrdfPairsSpec):
            return srdf_of(sc, w.pairs, f"watch[{i}]"), f"watch[{i}].pairs.srdf"
    return None


def _urdf_links(robot: Robot) -> list[str]:
    """Every link name of ``robot``: its bodies and frames and, for a robot read from a
    URDF, every ``<link>`` of the file (also those off the loaded chain)."""
    names = dict.fromkeys([*robot.body_names, *robot.link_names])
    src = robot.source or ""
    if src.lower().endswith(".urdf") and Path(src).is_file():
        root = read_xml(Path(src), src)
        names.update(
            dict.fromkeys(
                c.attrib["name"] for c in root.children if c.tag == "link" and "name" in c.attrib
            )
        )
    return list(names)


def srdf_watched_pairs(
    srdf: Srdf,
    robot: Robot,
    clouds: Mapping[str, PointCloud],
    source: str,
    where: str,
) -> list[tuple[str, str]]:
    """The pairs of ``clouds``' links (link → cloud, base to tool) that ``srdf`` does not
    disable (module docstring); an SRDF link the robot does not have is an
    :class:`~reachwise.errors.UnknownName`."""
    known = _urdf_links(robot)
    valid = set(known)
    for p in srdf.disabled:
        for name in (p.link1, p.link2):
            if name not in valid:
                raise UnknownName(source, f"link of robot {robot.name!r}", name, known, field=where)
    disabled = srdf.disabled_pairs()
    links = list(clouds)
    return [
        (a, b)
        for i, a in enumerate(links)
        for b in links[i + 1 :]
        if frozenset((a, b)) not in disabled
    ]


def named_pose(
    srdf: Srdf, name: str, robot: Robot, joint_names: Sequence[str], source: str, where: str
) -> list[float]:
    """The joint values of ``srdf``'s ``group_state`` ``name`` in ``robot``'s ``q``
    order (``joint_names``: the robot's movable joints' names, base to tool). Errors:
    an unknown pose (the valid ones and the closest), a joint the state leaves out, a
    value outside the joint's limits."""
    if name not in srdf.poses:
        raise UnknownName(source, "group_state", name, srdf.poses, field=where)
    state = srdf.poses[name]
    missing = [j for j in joint_names if j not in state]
    if missing:
        raise InputError(
            source, where, f"group_state {name!r} gives no value for joint(s) {', '.join(missing)}"
        )
    q = [float(state[j]) for j in joint_names]
    for k, (j, v) in enumerate(zip(joint_names, q, strict=True)):
        lo, hi = float(robot.lower[k]), float(robot.upper[k])
        if not lo - 1e-9 <= v <= hi + 1e-9:
            raise InputError(
                source,
                where,
                f"group_state {name!r}: {j} = {v:g} is outside its limits [{lo:g}, {hi:g}]",
            )
    return q
