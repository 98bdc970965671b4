"""Topology specs, templates and the enumerator (P-II §2, Table 1; pruning rules 1–5)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from reachwise import load_robot
from reachwise.errors import InputError
from reachwise.synthesis.problem import SynthesisProblem
from reachwise.synthesis.topology import (
    EnumerationRules,
    JointSpec,
    TemplateOptions,
    Topology,
    TopologySpec,
    builtin_set,
    canonical,
    enumerate_topologies,
    free_parameters,
    parse_rules,
    parse_topology,
    rotation_axes,
    to_template,
    topologies_from_specs,
    violations,
)
from reachwise.tasks.task import Task

H = math.pi / 2


# ---- spec and string form ------------------------------------------------------------------
def test_letters_only_take_the_default_twists() -> None:
    sp = parse_topology("RRPRRR")
    assert sp.types == "RRPRRR"
    assert sp.twists == pytest.approx((0.0, H, H, H, H, H))
    assert str(sp) == "R(0) R(90) P(90) R(90) R(90) R(90)"
    assert sp.n_joints == 6 and sp.n_prismatic == 1


def test_full_tokens_offsets_and_free_flags() -> None:
    sp = parse_topology("R(0) R(90,-90):a P(-90):d F(0, 45):- r")
    j = sp.joints
    assert [x.kind for x in j] == ["R", "R", "P", "F", "R"]
    assert j[1].theta == pytest.approx(-H) and j[1].free == "a"
    assert j[2].alpha == pytest.approx(-H) and j[2].free == "d"
    assert j[3].free == "" and j[3].theta == pytest.approx(math.pi / 4)
    assert sp.types == "RRPR"  # the fixed row has no joint variable
    assert parse_topology(str(sp)) == sp


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.sampled_from("RPF"),
            st.integers(-11, 12).map(lambda k: 15.0 * k),
            st.integers(-11, 12).map(lambda k: 15.0 * k),
            st.sampled_from(("ad", "a", "d", "")),
        ),
        min_size=1,
        max_size=8,
    ).filter(lambda rows: any(r[0] != "F" for r in rows))
)
def test_string_form_round_trips(rows: list[tuple[str, float, float, str]]) -> None:
    sp = TopologySpec(
        tuple(JointSpec(k, math.radians(a), math.radians(t), f) for k, a, t, f in rows)
    )
    again = parse_topology(str(sp))
    assert str(again) == str(sp)
    assert again.types == sp.types


@pytest.mark.parametrize(
    ("text", "match"),
    [("", "empty"), ("RRX", "character 3"), ("R(abc)", "character 2"), ("F F", "movable")],
)
def test_bad_strings_are_named(text: str, match: str) -> None:
    with pytest.raises(InputError, match=match):
        parse_topology(text)


def test_bad_joint_fields() -> None:
    with pytest.raises(InputError, match="kind"):
        JointSpec("Q")
    with pytest.raises(InputError, match="free"):
        JointSpec("R", free="x")
    with pytest.raises(InputError, match="finite"):
        JointSpec("R", alpha=math.inf)


# ---- templates ---------------------------------------------------------------------------
def test_template_frees_every_a_and_d_within_bounds_and_locks_twists() -> None:
    t = to_template("RRPRRR", TemplateOptions(minimal=False))
    free = t.design.free
    assert {(j, p) for kind, j, p in free if kind == "joint"} == {
        (j, p) for j in range(6) for p in ("a", "d")
    }
    assert all(p != "alpha" for _, _, p in free)
    assert [p for kind, _, p in free if kind == "base"] == ["x", "y", "z"]
    assert all(b == (-2.0, 2.0) for row in t.design.joints.values() for b in row.values())
    assert t.joints[2].type == "prismatic" and t.joints[2].limits == (0.0, 3.0)
    assert t.joints[0].limits == pytest.approx((-math.pi, math.pi))
    assert t.name == "R(0) R(90) P(90) R(90) R(90) R(90)"
    assert np.allclose(t.tool, np.eye(4))


def test_minimal_template_drops_exactly_redundant_parameters() -> None:
    sp = parse_topology("R(0) R(90) R(0) P(90) R(90) R(90)")
    free = free_parameters(sp)
    assert free[0] == set()  # a0, d1: base translation
    assert free[1] == {"a", "d"}
    assert free[2] == {"a"}  # d3: parallel to axis 2 whose offset is free
    assert free[3] == {"a", "d"}
    t = to_template(sp)
    assert t.design_names[:4] == ("a1", "d2", "a2", "a3")


def test_redundancy_claims_hold_kinematically(rng: np.random.Generator) -> None:
    """Rule behind ``minimal``: only d2 + d3 matters across parallel axes, and a0 / d1
    act like a base translation."""
    full = to_template("R(0) R(90) R(0) P(90) R(90) R(90)", TemplateOptions(minimal=False))
    Q = rng.uniform(-1, 1, (20, 6))
    Q[:, 3] = rng.uniform(0, 3, 20)
    dh = np.array(full.dh)
    dh[:, [0, 2]] = rng.uniform(-2, 2, (6, 2))
    dh2 = dh.copy()
    dh2[1, 2] += dh2[2, 2]
    dh2[2, 2] = 0.0
    a = full.with_parameters(dh=dh).fk(Q)
    b = full.with_parameters(dh=dh2).fk(Q)
    assert np.allclose(a, b, atol=1e-12)
    dh3 = dh.copy()
    dh3[0, 0] = dh3[0, 2] = 0.0
    base = np.eye(4)
    base[:3, 3] = [dh[0, 0], 0.0, dh[0, 2]]  # alpha0 = 0: z1 = base z
    c = full.with_parameters(dh=dh3, base=base).fk(Q)
    assert np.allclose(a, c, atol=1e-12)


def test_template_options_validate() -> None:
    with pytest.raises(InputError, match="length_bounds"):
        TemplateOptions(length_bounds=(1.0, -1.0))
    with pytest.raises(InputError, match=r"base_bounds\.yaw"):
        TemplateOptions(base_bounds={"yaw": (-1.0, 1.0)})
    assert TemplateOptions().symmetric
    assert not TemplateOptions(length_bounds=(0.0, 2.0)).symmetric


# ---- the P-II set --------------------------------------------------------------------------
def test_p2_set_is_the_six_configurations_of_table_1() -> None:
    topos = builtin_set("p2", load_robot)
    assert [t.name for t in topos] == [f"p2-man{i}" for i in range(1, 7)]
    types = [t.spec.types for t in topos]
    # Table 1: RRPRRRP, RRPRRRP, RRPRRR, RRPRRR, (PRRRRR: Table 7 orders it RP…), RRRRRRR
    assert types[:4] == ["RRPRRRP", "RRPRRRP", "RRPRRR", "RRPRRR"]
    assert sorted(types[4]) == sorted("PRRRRR")
    assert types[5] == "RRRRRRR"
    for t in topos:
        assert t.template.design.size > 0
        assert str(t.spec)  # every template has a spec string
    with pytest.raises(InputError, match="p2"):
        builtin_set("nope", load_robot)


def test_topologies_from_specs_drop_duplicates_keep_order() -> None:
    ts = topologies_from_specs(["RRPRRR", "R(0) R(90) P(90) R(90) R(90) R(90)", "PRRRRR"])
    assert [t.spec.types for t in ts] == ["RRPRRR", "PRRRRR"]
    assert isinstance(ts[0], Topology) and ts[0].template.name == ts[0].name


# ---- pruning rules ------------------------------------------------------------------------
def _rules() -> EnumerationRules:
    return EnumerationRules(min_joints=1, max_joints=8)


def test_rule_1_parallel_prismatic_pair() -> None:
    v = violations("R(0) R(90) P(90) P(0) R(90) R(90) R(90)", _rules())
    assert any(x.startswith("1 ") for x in v)
    assert not any(x.startswith("1 ") for x in violations("R R P P(90) R R R", _rules()))


def test_rule_2_coincident_revolute_axes() -> None:
    v = violations("R(0) R(90) R(0):d R(90) R(90) R(90)", _rules())
    assert any(x.startswith("2 ") for x in v)
    assert not any(x.startswith("2 ") for x in violations("R R R(0) R R R", _rules()))


def test_rule_3_more_than_three_parallel_revolutes() -> None:
    v = violations("R(0) R(90) R(0) R(0) R(0) R(90)", _rules())
    assert any(x.startswith("3 ") for x in v)
    assert not violations("R(0) R(90) R(0) R(0) R(90) R(90)", _rules())


def test_rule_4_rotation_axes() -> None:
    assert rotation_axes(parse_topology("P(0) P(90) P(90) R(90) R(0) R(90)")) == 2
    assert rotation_axes(parse_topology("R(0) P(90) R(-90)")) == 1  # P's twists cancel
    assert rotation_axes(parse_topology("R(0) P(90) R(90)")) == 1  # 180°: antiparallel
    assert rotation_axes(parse_topology("R(0) P(90) R(0)")) == 2
    v = violations("P(0) P(90) P(90) R(90) R(0) R(90)", _rules())
    assert any(x.startswith("4 ") for x in v)


def test_rule_5_mirror_equivalent_sign_patterns() -> None:
    v = violations("R(0) R(-90) P(90) R(90) R(90) R(90)", _rules())
    assert any(x.startswith("5 ") for x in v)
    assert str(canonical("R(0) R(-90) P(90) R(90) R(90) R(90)", _rules())) == (
        "R(0) R(90) P(-90) R(90) R(90) R(90)"
    )
    assert not violations("R(0) R(90) P(-90) R(90) R(90) R(90)", _rules())
    # no mirror rule when the bounds are not symmetric
    asym = TemplateOptions(length_bounds=(0.0, 2.0))
    assert not violations("R(0) R(-90) P(90) R(90) R(90) R(90)", _rules(), asym)


@pytest.mark.parametrize(
    ("text", "k"),
    [("R(0) R(90) P(90) R(-90) R(90) R(0)", 1), ("R(90) R(90) R(0) R(90) R(90) P(90)", 0),
     ("R(0) R(90) P(90) R(-90) R(90) R(0)", 4), ("R(0) F(90,30) R(90) R(90) R(90) R(0)", 1)],
)  # fmt: skip
def test_axis_reversal_gives_the_same_tool_poses(
    text: str, k: int, rng: np.random.Generator
) -> None:
    """Rule 5's proof: reversing axis k maps (alpha_k, alpha_k+1, theta_k, d_k, q_k) to
    (alpha_k + π, alpha_k+1 − π, −theta_k, −d_k, −q_k) and leaves every tool pose."""
    opts = TemplateOptions(minimal=False)
    A = to_template(text, opts)
    dh = np.array(A.dh)
    dh[:, [0, 2]] = rng.uniform(-2, 2, (len(dh), 2))
    dhB = dh.copy()
    dhB[k, 1] += math.pi
    dhB[k + 1, 1] -= math.pi
    dhB[k, 3] = -dhB[k, 3]
    dhB[k, 2] = -dhB[k, 2]
    ra, rb = A.with_parameters(dh=dh), A.with_parameters(dh=dhB)
    Q = rng.uniform(A.lower, np.minimum(A.upper, 3.0), (25, A.n))
    QB = Q.copy()
    qk = A.movable_joints.index(k) if k in A.movable_joints else None
    if qk is not None:
        QB[:, qk] = -QB[:, qk]
    assert np.allclose(ra.fk(Q), rb.fk(QB), atol=1e-12)


# ---- enumeration ------------------------------------------------------------------------------
def test_enumeration_obeys_the_rules_and_is_deterministic() -> None:
    rules = EnumerationRules(min_joints=5, max_joints=6, max_prismatic=1, first_axis="vertical")
    a = enumerate_topologies(rules)
    b = enumerate_topologies(rules)
    assert [str(s) for s in a] == [str(s) for s in b]
    assert len({str(s) for s in a}) == len(a)
    assert a
    for s in a:
        assert 5 <= s.n_joints <= 6
        assert s.n_prismatic <= 1
        assert s.joints[0].alpha == 0.0
        assert all(j.theta == 0.0 and j.free == "ad" for j in s.joints)
        assert not violations(s, rules)


def test_vectorized_pruning_agrees_with_the_rule_checks() -> None:
    rules = EnumerationRules(min_joints=4, max_joints=5, twists=(0.0, H, -H, math.pi))
    kept = {str(s) for s in enumerate_topologies(rules)}
    loose = replace(rules, mirror=False, max_parallel_revolute=99, min_rotation_axes=0)
    every = enumerate_topologies(loose)
    assert len(every) > len(kept)
    for s in every[::7]:
        assert (not violations(s, rules)) == (str(s) in kept), str(s)


def test_mirror_rule_keeps_one_of_each_class() -> None:
    rules = EnumerationRules(max_prismatic=1)
    kept = {str(s) for s in enumerate_topologies(rules)}
    every = enumerate_topologies(replace(rules, mirror=False))
    classes = {str(canonical(s, rules)) for s in every}
    assert classes == {c for c in classes if c in kept}
    assert len(kept) < len(every)


def test_first_axis_types_and_patterns() -> None:
    hor = enumerate_topologies(EnumerationRules(first_axis="horizontal", max_prismatic=0))
    assert hor and all(abs(s.joints[0].alpha) == pytest.approx(H) for s in hor)
    pr = enumerate_topologies(EnumerationRules(first_types="P", max_prismatic=1))
    assert pr and all(s.types[0] == "P" for s in pr)
    pats = enumerate_topologies(EnumerationRules(patterns=("RRPRRR", "PRRRRR")))
    assert {s.types for s in pats} == {"RRPRRR", "PRRRRR"}
    only_r = enumerate_topologies(EnumerationRules(types="R", min_joints=6, max_joints=6))
    assert only_r and all(s.types == "RRRRRR" for s in only_r)


def test_sample_is_evenly_spaced_and_stable() -> None:
    full = enumerate_topologies(EnumerationRules())
    s = enumerate_topologies(EnumerationRules(sample=25))
    assert len(s) == 25
    names = [str(x) for x in full]
    idx = [names.index(str(x)) for x in s]
    assert idx == sorted(idx) and idx[0] == 0 and idx[-1] == len(full) - 1
    assert [str(x) for x in enumerate_topologies(EnumerationRules(sample=25))] == [
        str(x) for x in s
    ]


def test_parse_rules() -> None:
    r = parse_rules("joints=6-7 prismatic=1-2; twists=0,90 first=vertical sample=10 mirror=off")
    assert (r.min_joints, r.max_joints, r.min_prismatic, r.max_prismatic) == (6, 7, 1, 2)
    assert r.twists == pytest.approx((H, 0.0))
    assert r.first_axis == "vertical" and r.sample == 10 and not r.mirror
    r2 = parse_rules("patterns=rrprrr,prrrrr first_type=R parallel=2 rotations=2 types=R")
    assert r2.patterns == ("RRPRRR", "PRRRRR") and r2.first_types == "R"
    assert r2.max_parallel_revolute == 2 and r2.min_rotation_axes == 2
    for bad, match in [("joints=x", "joints"), ("foo=1", "unknown"), ("twists=45", "90"),
                       ("first=up", "first_axis"), ("joints", "KEY=VALUE"),
                       ("types=Q", "types"), ("joints=7-6", "joints")]:  # fmt: skip
        with pytest.raises(InputError, match=match):
            parse_rules(bad)


def test_enumerated_templates_are_valid_synthesis_problems() -> None:
    task = Task.from_arrays("one", np.array([[3.0, 0.0, 1.0]]), axes=[[1, 0, 0]], dims=5)
    for s in enumerate_topologies(EnumerationRules(sample=10, max_joints=7)):
        prob = SynthesisProblem(to_template(s), task)
        assert prob.p == len(prob.design_names) >= 3
