"""The bodies of a robot: the links its shapes belong to, and the frames they ride on.

A robot's frames are the rows of ``Robot.fk_all`` (one per DH row, the base and the
tool). A robot read from a URDF has more links than frames: a flange, a force-torque
sensor or a hand fixed to the last joint, a finger held at rest, all ride rigidly on
one frame. Each of them is a :class:`Body` of its own, named as in the URDF, so its
shapes, its cloud and its collision pairs stay its own; ``frame`` says which row of
``fk_all`` carries it (its shapes are given in that frame) and ``parent`` is the body
it hangs from in the URDF tree (``""`` for the root), joined by URDF joint ``joint``.

A robot without bodies of its own (a DH table from a YAML file) has one body per frame,
each the child of the one before (:func:`chain_bodies`).

Which bodies touch by design follows MoveIt's rule (``compute_default_collisions``):
two bodies are **adjacent** when one joint joins them, or when they are joined through
bodies without shapes only (:func:`adjacent_bodies`).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass

__all__ = ["Body", "adjacent_bodies", "chain_bodies"]


@dataclass(frozen=True)
class Body:
    """One link of a robot (module docstring): the frame (a ``Robot.link_names`` entry)
    it rides on, its parent body (``""`` at the root) and the joint between them."""

    frame: str
    parent: str = ""
    joint: str = ""


def chain_bodies(frames: tuple[str, ...]) -> dict[str, Body]:
    """One body per frame, each hanging from the one before (a serial chain)."""
    return {f: Body(f, frames[i - 1] if i else "") for i, f in enumerate(frames)}


def adjacent_bodies(bodies: Mapping[str, Body], shaped: Collection[str], a: str, b: str) -> bool:
    """Whether bodies ``a`` and ``b`` are adjacent by MoveIt's rule: one joint joins
    them, or a path of joints whose inner bodies all lack shapes (are not in
    ``shaped``)."""
    near: dict[str, set[str]] = {n: set() for n in bodies}
    for n, body in bodies.items():
        if body.parent:
            near[n].add(body.parent)
            near.setdefault(body.parent, set()).add(n)
    seen = {a}
    todo = [a]
    while todo:
        for m in near.get(todo.pop(), ()):
            if m == b:
                return True
            if m not in seen and m not in shaped:
                seen.add(m)
                todo.append(m)
    return False
