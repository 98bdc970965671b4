"""The compiled tick's typed inputs: a mis-shaped or mistyped group is refused with an
``InputError`` that names the group and the field, before any motion is computed."""

from __future__ import annotations

import numpy as np
import pytest

import reachwise
from reachwise.control import AvoidancePoints, Controller, ControllerConfig, Goal
from reachwise.control.tick.step import control_step, run_tick
from reachwise.control.tick.types import (
    MEM_COLS,
    AvoidanceRows,
    AvoidanceSettings,
    Gains,
    GuardMemory,
    JointLimits,
    Target,
    TickDiagnostics,
)
from reachwise.errors import InputError

Q = np.array([0.1, 0.3, 0.8, 0.3, 0.1, 0.4, 0.5, 0.8])


@pytest.fixture(scope="module")
def sb60() -> reachwise.Robot:
    return reachwise.load_robot("sb60")


def _groups(robot: reachwise.Robot) -> dict[str, tuple]:  # type: ignore[type-arg]
    n = robot.n
    F = robot.fk_all(Q)
    k = robot.link_index("link_5")
    return {
        "chain": robot.arrays,
        "limits": JointLimits(
            lower=robot.lower,
            upper=robot.upper,
            vmax=robot.vmax,
            usable=np.ones(n, np.bool_),
            passive=np.zeros(n, np.bool_),
            zone=np.full(n, 0.1),
        ),
        "gains": Gains(
            kv=1.0,
            kw=1.0,
            v_max=0.5,
            w_max=0.3,
            lambda_max=0.05,
            epsilon=0.05,
            mu=2e-4,
            v_rep_max=1.0,
            k_limit=2.0,
        ),  # the ControllerConfig defaults
        "settings": AvoidanceSettings(
            avoidance=True,
            guard=True,
            stop_distance=0.04,
            approach_speed=0.5,
            reaction_time=0.0,
            velocity_aware=True,
        ),
        "target": Target(pose=robot.fk(Q + 0.05), six=True),
        "rows": AvoidanceRows(
            a_link=np.array([k]),
            a_point=F[k, :3, 3][None].copy(),
            b_link=np.array([-1]),
            b_point=np.full((1, 3), np.nan),
            normal=np.array([[0.0, 0.0, 1.0]]),
            obstacle_velocity=np.zeros((1, 3)),
            distance=np.array([0.1]),
            margin=np.array([0.3]),
            task_space=np.array([False]),
        ),
        "memory": GuardMemory(lines=np.zeros((4, MEM_COLS)), depth=2),
    }


def _run(g: dict[str, tuple], q: np.ndarray = Q) -> tuple[np.ndarray, TickDiagnostics]:  # type: ignore[type-arg]
    return run_tick(
        g["chain"], g["limits"], g["gains"], g["settings"], g["target"], g["rows"],  # type: ignore[arg-type]
        g["memory"], q,  # type: ignore[arg-type]
    )  # fmt: skip


def test_the_checked_entry_is_the_controllers_tick(sb60: reachwise.Robot) -> None:
    g = _groups(sb60)
    qdot, diag = _run(g)
    assert isinstance(diag, TickDiagnostics) and diag.active_points == 1
    assert g["memory"].lines[:, -1].max() == 1.0  # the row was remembered
    # the same tick through the controller (same gains as ControllerConfig's defaults)
    rows = g["rows"]
    pts = AvoidancePoints(1, 0.0, 0.0, *rows[:5], rows.distance, rows.margin, rows.task_space)
    c = Controller(sb60, ControllerConfig())
    qd2, st = c.step(Q, Goal(g["target"].pose), pts, 0.0)
    np.testing.assert_array_equal(qdot, qd2)
    assert (st.sigma_min, st.damping, st.task_scale) == (
        diag.sigma_min,
        diag.damping,
        diag.task_scale,
    )


@pytest.mark.parametrize(
    ("group", "field", "bad", "match"),
    [
        ("limits", "vmax", lambda g: np.ones(7), r"JointLimits: vmax: expected shape \(n,\)"),
        ("limits", "lower", lambda g: g.lower.astype(np.float32), "JointLimits: lower: .*dtype"),
        ("limits", "usable", lambda g: np.ones(8), "JointLimits: usable: .*dtype bool"),
        ("chain", "dh", lambda g: np.ascontiguousarray(g.dh[:, :3]), "Chain: dh: .*axis 1"),
        ("chain", "base", lambda g: np.eye(4)[:, ::-1], "Chain: base: must be C-contiguous"),
        ("gains", "kv", lambda g: 1, "Gains: kv: expected a float"),
        ("settings", "guard", lambda g: 1.0, "AvoidanceSettings: guard: expected a bool"),
        ("target", "pose", lambda g: np.eye(3), r"Target: pose: expected shape \(4, 4\)"),
        ("rows", "normal", lambda g: np.zeros((2, 3)), r"AvoidanceRows: normal: .*m = 1"),
        ("rows", "a_link", lambda g: np.array([99]), "AvoidanceRows: a_link: frame indices"),
        ("memory", "lines", lambda g: np.zeros((4, 10)), "GuardMemory: lines: .*axis 1"),
        ("memory", "lines", lambda g: np.zeros((1, MEM_COLS)), "GuardMemory: lines: needs"),
    ],
)
def test_a_bad_group_is_refused_before_any_motion(  # type: ignore[no-untyped-def]
    sb60: reachwise.Robot, group, field, bad, match
) -> None:
    g = _groups(sb60)
    g[group] = g[group]._replace(**{field: bad(g[group])})
    mem = g["memory"].lines
    mem[0] = 0.5  # a remembered line that a tick would age
    before = mem.copy()
    with pytest.raises(InputError, match=match):
        _run(g)
    np.testing.assert_array_equal(mem, before)  # nothing was computed, nothing aged


def test_q_of_the_wrong_length_is_refused(sb60: reachwise.Robot) -> None:
    with pytest.raises(InputError, match=r"q: expected a float64 array of shape \(8,\)"):
        _run(_groups(sb60), Q[:7].copy())


def test_the_compiled_entry_refuses_other_types(sb60: reachwise.Robot) -> None:
    g = _groups(sb60)
    args = [tuple(g[k]) for k in ("chain", "limits", "gains", "settings", "target", "rows")]
    mem = tuple(g["memory"])
    control_step(*args, mem, Q)  # the declared types
    with pytest.raises(TypeError):
        control_step(*args, mem, Q.astype(np.float32))
    with pytest.raises(TypeError):  # two groups swapped
        control_step(args[1], args[0], *args[2:], mem, Q)


def test_controller_refuses_a_frame_index_outside_the_chain(sb60: reachwise.Robot) -> None:
    c = Controller(sb60)
    goal = Goal(sb60.fk(Q + 0.05))
    F = sb60.fk_all(Q)
    ok = AvoidancePoints(
        1, 0.0, 0.0, np.array([5]), F[5, :3, 3][None], np.array([-1]), np.full((1, 3), np.nan),
        np.array([[0.0, 0.0, 1.0]]), np.array([0.1]), np.array([0.3]), np.array([False]),
    )  # fmt: skip
    c.step(Q, goal, ok, 0.0)
    mem = c._mem.copy()
    for seq, (field, value) in enumerate((("a_link", 42), ("b_link", -2)), start=2):
        bad = AvoidancePoints(
            seq, 0.01, 0.01, np.array([42 if field == "a_link" else 5]), F[5, :3, 3][None],
            np.array([value if field == "b_link" else -1]), F[3, :3, 3][None],
            np.array([[0.0, 0.0, 1.0]]), np.array([0.1]), np.array([0.3]), np.array([False]),
        )  # fmt: skip
        with pytest.raises(InputError, match=f"avoidance points: {field}: frame index"):
            c.step(Q, goal, bad, 0.01)
        np.testing.assert_array_equal(c._mem, mem)  # nothing was computed, nothing aged
