"""Serial topologies: a compact spec, its design template, and the enumerator (P-II §2, §5).

Topology synthesis (P-II §2, Fig. 1; thesis §4.2, §5.1) decides *which* chain to build
— the number, type and order of the joints and the twist between consecutive axes —
before the dimensional synthesis sizes it. P-II hand-picks six topologies (Table 1)
with locked twist angles; it notes that "all possible topologies [could be] generated
automatically and then optimized". This package does that, one concept per module:

- ``spec`` — ``JointSpec``/``TopologySpec`` and the string grammar (``parse_topology``);
- ``template`` — the design template ``Robot`` of a spec (``to_template``);
- ``rules`` — ``EnumerationRules`` and their ``KEY=VALUE`` form (``parse_rules``);
- ``pruning`` — the five pruning rules (``violations``, ``canonical``, ``rotation_axes``);
- ``enumeration`` — ``enumerate_topologies``;
- ``sets`` — ``Topology`` (a sweep candidate) and the named sets (``builtin_set``).

Pure: no files, no clocks, no printing (``builtin_set`` takes the robot loader).
"""

from __future__ import annotations

from reachwise.synthesis.topology.enumeration import enumerate_topologies
from reachwise.synthesis.topology.pruning import canonical, rotation_axes, violations
from reachwise.synthesis.topology.rules import (
    DEFAULT_TWISTS,
    FIRST_AXES,
    EnumerationRules,
    parse_rules,
)
from reachwise.synthesis.topology.sets import (
    BUILTIN_SETS,
    Topology,
    builtin_set,
    topologies_from_specs,
)
from reachwise.synthesis.topology.spec import (
    FREE_FLAGS,
    KINDS,
    JointSpec,
    TopologySpec,
    as_spec,
    parse_topology,
)
from reachwise.synthesis.topology.template import TemplateOptions, free_parameters, to_template

__all__ = [
    "BUILTIN_SETS",
    "DEFAULT_TWISTS",
    "FIRST_AXES",
    "FREE_FLAGS",
    "KINDS",
    "EnumerationRules",
    "JointSpec",
    "TemplateOptions",
    "Topology",
    "TopologySpec",
    "as_spec",
    "builtin_set",
    "canonical",
    "enumerate_topologies",
    "free_parameters",
    "parse_rules",
    "parse_topology",
    "rotation_axes",
    "to_template",
    "topologies_from_specs",
    "violations",
]
