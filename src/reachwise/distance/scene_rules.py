"""The pair rules over a robot's objects: self-collision, environment and robot pairs.

Each rule watches pairs (P-V Table 1: which pairs to watch, with which margin) through
the scene's own :meth:`~reachwise.distance.scene.SceneLike.watch`, so it is written
once for any :class:`~reachwise.distance.scene.SceneLike`. Each is a scene operation
that changes the scene (:func:`~reachwise.distance.scene_ops.scene_change`): the
in-process :class:`~reachwise.distance.scene.Scene` has them as its methods
``watch_self``, ``watch_environment`` and ``watch_robots``, and a remote scene carries
the same calls to its server, which runs them on its scene.
"""

from __future__ import annotations

from collections.abc import Iterable

from reachwise.distance.pairs import WatchedPair
from reachwise.distance.scene_ops import scene_change
from reachwise.distance.scene_types import OnLink, RobotLike, SceneLike
from reachwise.errors import InputError, UnknownName

__all__ = ["watch_environment", "watch_robots", "watch_self"]


@scene_change
def watch_self(
    scene: SceneLike,
    robot: str,
    margin: float,
    exclude: Iterable[tuple[str, str]] = (),
) -> tuple[WatchedPair, ...]:
    """Self-collision pairs of ``robot``: every two of its objects except those on
    the same link, on adjacent links (neighbours in ``link_names``: joint i joins
    link_{i-1} and link_i; the tool is adjacent to the last link) and the pairs in
    ``exclude`` (each a pair of link names or object names, either order)."""
    r = _robot(scene, robot)
    index = {n: i for i, n in enumerate(r.link_names)}
    excl = {frozenset(e) for e in exclude}
    objs = scene.robot_objects(robot)
    out = []
    for i, oa in enumerate(objs):
        for ob in objs[i + 1 :]:
            la = oa.source.link  # type: ignore[union-attr]
            lb = ob.source.link  # type: ignore[union-attr]
            if abs(index[la] - index[lb]) <= 1:
                continue
            if frozenset((la, lb)) in excl or frozenset((oa.name, ob.name)) in excl:
                continue
            out.append(scene.watch(oa.name, ob.name, margin, kind="self"))
    return tuple(out)


@scene_change
def watch_environment(
    scene: SceneLike, robot: str, margin: float, objects: Iterable[str] | None = None
) -> tuple[WatchedPair, ...]:
    """Pairs of every object of ``robot`` with every object not on a robot (or with
    the named ``objects``)."""
    mine = scene.robot_objects(robot)
    every = scene.objects
    if objects is None:
        others = [o.name for o in every.values() if not isinstance(o.source, OnLink)]
    else:
        others = []
        for n in objects:
            if n not in every:
                raise UnknownName("scene", "object", n, every)
            others.append(n)
    return tuple(
        scene.watch(o.name, e, margin, kind="robot-environment") for o in mine for e in others
    )


@scene_change
def watch_robots(
    scene: SceneLike, robot_a: str, robot_b: str, margin: float
) -> tuple[WatchedPair, ...]:
    """Pairs of every object of ``robot_a`` with every object of ``robot_b``."""
    if robot_a == robot_b:
        raise InputError("scene", "watch_robots", "use watch_self for one robot")
    oa = scene.robot_objects(robot_a)
    ob = scene.robot_objects(robot_b)
    return tuple(scene.watch(x.name, y.name, margin, kind="robot-robot") for x in oa for y in ob)


def _robot(scene: SceneLike, name: str) -> RobotLike:
    robots = scene.robots
    r = robots.get(name)
    if r is None:
        raise UnknownName("scene", "robot", name, robots)
    return r
