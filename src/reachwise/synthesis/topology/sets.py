"""Candidates of a sweep: ``Topology`` (name, template, spec) and the named sets.

``builtin_set("p2", load_robot)``: the six configurations of P-II Table 1. The packaged
templates are files, so the caller hands in the loader (``reachwise.load_robot``): the
synthesis layer reads no files.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from reachwise.errors import UnknownName
from reachwise.kinematics.robot import Robot
from reachwise.synthesis.topology.spec import _SRC, TopologySpec, as_spec
from reachwise.synthesis.topology.template import TemplateOptions, to_template

BUILTIN_SETS: dict[str, tuple[str, ...]] = {
    "p2": tuple(f"p2-man{i}" for i in range(1, 7)),
}


@dataclass(frozen=True, eq=False)
class Topology:
    """A candidate of a sweep: its ``name`` (the key it is stored under), its design
    ``template`` and its ``spec`` (``str(spec)`` is the canonical string)."""

    name: str
    template: Robot
    spec: TopologySpec

    @classmethod
    def from_spec(
        cls, spec: TopologySpec | str, options: TemplateOptions | None = None
    ) -> Topology:
        sp = as_spec(spec)
        return cls(str(sp), to_template(sp, options), sp)

    @classmethod
    def from_robot(cls, robot: Robot, name: str | None = None) -> Topology:
        return cls(name or robot.name, robot, TopologySpec.from_robot(robot))


def builtin_set(name: str, load_robot: Callable[[str], Robot]) -> list[Topology]:
    """A named set of topologies; ``p2``: the six configurations of P-II Table 1 as the
    packaged templates ``p2-man1`` … ``p2-man6`` (DH tables 3–7, bounds of §5.1), each
    read by ``load_robot`` (pass ``reachwise.load_robot``)."""
    if name not in BUILTIN_SETS:
        raise UnknownName(_SRC, "set", name, BUILTIN_SETS)
    return [Topology.from_robot(load_robot(r)) for r in BUILTIN_SETS[name]]


def topologies_from_specs(
    specs: Sequence[TopologySpec | str], options: TemplateOptions | None = None
) -> list[Topology]:
    """Topologies of the given specs (duplicates by canonical string dropped, order kept)."""
    out: dict[str, Topology] = {}
    for s in specs:
        t = Topology.from_spec(s, options)
        out.setdefault(t.name, t)
    return list(out.values())
