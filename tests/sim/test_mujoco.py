"""The MuJoCo dynamics check (issue 9): model FK = reachwise FK, the velocity servo
against its closed-form first-order response, passive joints swinging with the chosen
damping, and the p3/p5 scenarios run on MuJoCo as the plant."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

import reachwise
from reachwise.errors import InputError, MissingDependency
from reachwise.io.robot_clouds import link_mesh
from reachwise.kinematics.robot import Joint, LinkGeometry, Robot
from reachwise.sim.mujoco_model import mujoco_model, require_mujoco
from reachwise.sim.mujoco_plant import (
    MujocoPlant,
    MujocoPlantConfig,
    plant_comparison,
)
from reachwise.sim.plant import PlantConfig, hanging_joints
from reachwise.sim.simulate import simulate
from tests.conftest import random_chain

try:
    import mujoco
except ImportError:  # the optional "sim" extra: the tests that need it are skipped
    mujoco = None

G = 9.81
#: MuJoCo itself is needed (per test: the missing-extra error and the pure checks run
#: without it).
needs_mujoco = pytest.mark.skipif(
    mujoco is None, reason='needs MuJoCo: pip install "reachwise[sim]"'
)


def _random_q(robot: Robot, rng: np.random.Generator, m: int) -> np.ndarray:
    lo = np.where(np.isfinite(robot.lower), robot.lower, -1.5)
    hi = np.where(np.isfinite(robot.upper), robot.upper, 1.5)
    return rng.uniform(lo, hi, size=(m, robot.n))


def _fk_error(robot: Robot, rng: np.random.Generator, m: int = 100) -> float:
    mj = mujoco_model(robot)
    data = mujoco.MjData(mj.model)
    err = 0.0
    for q in _random_q(robot, rng, m):
        F = mj.frames(q, data)
        err = max(err, float(np.abs(F - robot.fk_all(q)).max()))
        err = max(err, float(np.abs(F[-1] - robot.fk(q)).max()))
    return err


# ------------------------------------------------------------------ model = reachwise FK


@needs_mujoco
@pytest.mark.parametrize("name", ["panda", "puma560", "stanford", "sb60", "hiab-xs033"])
def test_model_fk_equals_reachwise_fk(name: str, rng: np.random.Generator) -> None:
    """Body poses and the tool site after ``mj_kinematics`` equal ``Robot.fk_all`` /
    ``Robot.fk`` to 1e-9 at 100 random poses (stanford: classic DH with a prismatic
    joint; hiab-xs033: two passive joints; panda: a fixed flange row)."""
    assert _fk_error(reachwise.load_robot(name), rng) < 1e-9


@needs_mujoco
@pytest.mark.parametrize("classic", [False, True])
def test_model_fk_of_random_chains(classic: bool, rng: np.random.Generator) -> None:
    """Random chains of both conventions with revolute, prismatic and fixed rows and
    random base and tool frames (classic DH: the joint acts about the parent's z)."""
    for _ in range(5):
        assert _fk_error(random_chain(rng, 7, classic=classic), rng, 20) < 1e-9


@needs_mujoco
def test_model_structure_follows_the_robot() -> None:
    """Ranges in radians/metres, a velocity servo (ctrlrange ±v_max, force kv(u − q̇))
    per actuated joint, none on the passive ones, contacts off, inertia from geometry."""
    robot = reachwise.load_robot("hiab-xs033")
    mj = mujoco_model(robot, kv=7.0, passive_damping=3.0, density=500.0)
    m = mj.model
    jid = m.dof_jntid[mj.dof]
    np.testing.assert_allclose(m.jnt_range[jid, 0], robot.lower)
    np.testing.assert_allclose(m.jnt_range[jid, 1], robot.upper)
    assert list(m.jnt_type[jid]) == [
        mujoco.mjtJoint.mjJNT_SLIDE if p else mujoco.mjtJoint.mjJNT_HINGE for p in robot.prismatic
    ]
    act = np.asarray(robot.actuated)
    assert m.nu == act.sum() == 4 and (mj.actuator[~act] == -1).all()
    a = mj.actuator[act]
    np.testing.assert_allclose(m.actuator_ctrlrange[a, 1], robot.vmax[act])
    np.testing.assert_allclose(m.actuator_ctrlrange[a, 0], -robot.vmax[act])
    np.testing.assert_allclose(m.actuator_gainprm[a, 0], 7.0)
    np.testing.assert_allclose(m.actuator_biasprm[a, :3], [[0.0, 0.0, -7.0]] * 4)
    np.testing.assert_allclose(m.dof_damping[mj.dof[~act]], 3.0)
    np.testing.assert_allclose(m.dof_damping[mj.dof[act]], 0.0)
    assert m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    assert (m.geom_contype == 0).all() and (m.geom_conaffinity == 0).all()
    # the grabber (link_6) is a 0.7 x 0.5 x 0.4 m box: mass = density x volume
    assert m.body_mass[mj.body[6]] == pytest.approx(500.0 * 0.7 * 0.5 * 0.4, rel=1e-12)
    np.testing.assert_allclose(m.body_ipos[mj.body[6]], [0.6, 0.0, 0.0], atol=1e-12)


@needs_mujoco
def test_mesh_link_inertia_from_its_convex_hull(tmp_path: Path) -> None:
    """A mesh link's mass and inertia: a 0.6 x 0.3 x 0.2 m box written as an OBJ file
    must weigh density x volume with the box's inertia, by hand."""
    import trimesh

    lx, ly, lz = 0.6, 0.3, 0.2
    trimesh.creation.box(extents=(lx, ly, lz)).export(tmp_path / "part.obj")
    g = LinkGeometry("mesh", mesh="part.obj", origin=_at(0.2, 0.0, 0.0))
    robot = Robot("meshy", (Joint("revolute"),), geometry={"link_1": g})
    with pytest.raises(InputError):  # not read yet and not where the robot file is
        mujoco_model(robot, density=800.0)
    meshes = {"link_1": link_mesh(robot, "link_1", tmp_path)}  # as a resolved scenario has
    mj = mujoco_model(robot, density=800.0, meshes=meshes)
    b = mj.body[1]
    mass = 800.0 * lx * ly * lz
    assert mj.model.body_mass[b] == pytest.approx(mass, rel=1e-9)
    np.testing.assert_allclose(mj.model.body_ipos[b], [0.2, 0.0, 0.0], atol=1e-12)
    box = mass / 12.0 * np.array([ly**2 + lz**2, lx**2 + lz**2, lx**2 + ly**2])
    np.testing.assert_allclose(np.sort(mj.model.body_inertia[b]), np.sort(box), rtol=1e-9)


# ------------------------------------------------------------------ the velocity servo


def _turntable(vmax: float = 1.0) -> tuple[Robot, float]:
    """One revolute joint about the vertical axis carrying a 0.4 x 0.2 x 0.1 m box whose
    centre is 0.3 m out along x: no gravity torque about the axis. Returns the robot
    and the box's inertia about the axis, by hand (ρ = 1000 kg/m³)."""
    lx, ly, lz, c = 0.4, 0.2, 0.1, 0.3
    box = LinkGeometry("box", size=(lx, ly, lz), origin=_at(c, 0.0, 0.0))
    robot = Robot(
        "turntable",
        (Joint("revolute", limits=(-100.0, 100.0), vmax=vmax),),
        geometry={"link_1": box},
    )
    mass = 1000.0 * lx * ly * lz
    return robot, mass * (lx**2 + ly**2) / 12.0 + mass * c**2


def _at(x: float, y: float, z: float) -> tuple[tuple[float, ...], ...]:
    return ((1, 0, 0, x), (0, 1, 0, y), (0, 0, 1, z), (0, 0, 0, 1))


@needs_mujoco
def test_servo_tracks_a_constant_velocity_as_a_first_order_lag() -> None:
    """``kv (u − q̇) = I q̈`` has ``q̇ = u (1 − e^{−t/τ})``, ``τ = I/kv``; the plant sets
    ``kv = I/τ`` from the model's inertia, which must be the box's inertia by hand.
    Tolerance: 1.5 % of ``u`` during the transient (the implicit integrator at a 1 ms
    substep against a 20 ms lag), 1e-4 of ``u`` after 10 τ."""
    robot, inertia = _turntable()
    tau, u, dt = 0.02, 0.6, 0.01
    plant = MujocoPlant(robot, [0.0], MujocoPlantConfig(servo_time_constant=tau))
    assert plant.kv[0] * tau == pytest.approx(inertia, rel=1e-9)
    ts, v, q = [], [], []
    for k in range(1, 51):
        plant.step([u], dt)
        ts.append(k * dt)
        v.append(plant.qdot[0])
        q.append(plant.q[0])
    t = np.array(ts)
    v_exact = u * (1.0 - np.exp(-t / tau))
    q_exact = u * (t - tau * (1.0 - np.exp(-t / tau)))
    assert np.abs(np.array(v) - v_exact).max() < 0.015 * u
    assert np.abs(np.array(q) - q_exact).max() < 0.015 * u * tau
    late = t >= 10 * tau
    assert np.abs(np.array(v)[late] - u).max() < 1e-4 * u
    tr = plant.tracking()
    assert tr["ticks"] == 50
    assert tr["first_order_error_max"] < 0.015 * u  # the single joint IS the ideal servo
    assert tr["position_lag_max"] == pytest.approx(u * tau, rel=0.02)  # lag → τ u
    assert tr["position_lag_max"] <= tr["position_lag_bound"] * 1.02


@needs_mujoco
def test_commands_beyond_vmax_are_saturated() -> None:
    robot, _ = _turntable(vmax=0.5)
    plant = MujocoPlant(robot, [0.0], MujocoPlantConfig(servo_time_constant=0.02))
    for sign in (1.0, -1.0):
        for _ in range(40):
            plant.step([sign * 3.0], 0.01)
        assert plant.qdot[0] == pytest.approx(sign * 0.5, abs=1e-6)
    tr = plant.tracking()
    assert tr["velocity_error_max"] <= 1.0 + 1e-9  # against u = ±v_max, not the command


@needs_mujoco
def test_rate_limit_bounds_the_acceleration() -> None:
    """A hydraulic rate limit a_max slews the setpoint: the joint's acceleration stays
    ≤ a_max and it reaches u no sooner than u / a_max."""
    robot, _ = _turntable(vmax=2.0)
    plant = MujocoPlant(robot, [0.0], MujocoPlantConfig(servo_time_constant=0.05, rate_limit=1.0))
    v = [0.0]
    for _ in range(150):
        plant.step([1.0], 0.01)
        v.append(plant.qdot[0])
    acc = np.diff(v) / 0.01
    assert acc.max() <= 1.0 + 1e-6
    assert v[90] < 0.9 < v[-1]


def _pendulum_arm(passive: bool) -> tuple[Robot, float, float, float]:
    """Vertical-axis joint, then a horizontal-axis joint (modified DH alpha = -90°)
    carrying a box 0.5 m out along its x. Returns robot, the box mass, its centre
    distance and its inertia about the horizontal axis (by hand)."""
    lx, ly, lz, c = 0.2, 0.1, 0.1, 0.5
    box = LinkGeometry("box", size=(lx, ly, lz), origin=_at(c, 0.0, 0.0))
    robot = Robot(
        "arm",
        (
            Joint("revolute", limits=(-3.0, 3.0), vmax=1.0),
            Joint("revolute", alpha=-math.pi / 2, limits=(-3.0, 3.0), vmax=1.0, passive=passive),
        ),
        geometry={"link_2": box},
    )
    mass = 1000.0 * lx * ly * lz
    return robot, mass, c, mass * (lx**2 + ly**2) / 12.0 + mass * c**2


@needs_mujoco
def test_bias_feedforward_holds_against_gravity_and_its_absence_sags() -> None:
    """With the arm horizontal and u = 0, the feed-forward holds it still; without it
    the servo sags at the steady rate G/kv = m g c τ / I (q̇ = −G/kv at balance)."""
    robot, mass, c, inertia = _pendulum_arm(passive=False)
    tau = 0.02
    hold = MujocoPlant(robot, [0.0, 0.0], MujocoPlantConfig(servo_time_constant=tau))
    sag = MujocoPlant(
        robot, [0.0, 0.0], MujocoPlantConfig(servo_time_constant=tau, bias_feedforward=False)
    )
    for _ in range(20):  # 10 τ
        hold.step([0.0, 0.0], 0.01)
        sag.step([0.0, 0.0], 0.01)
    assert np.abs(hold.q).max() < 1e-9 and np.abs(hold.qdot).max() < 1e-9
    # gravity pulls the box (at +x of link_2, horizontal) down; the joint's sign follows
    # from its axis, the magnitude from the balance kv q̇ = G cos(q)
    expected = mass * G * c * math.cos(sag.q[1]) * tau / inertia
    assert abs(sag.qdot[1]) == pytest.approx(expected, rel=0.02)
    assert sag.q[1] * sag.qdot[1] > 0  # it keeps sagging the same way


@needs_mujoco
def test_passive_joint_hangs_at_rest_and_swings_with_the_chosen_damping() -> None:
    """A passive joint starts at its hanging rest (no motion under u = 0); pushed aside
    it swings back with the damping ratio ζ: first overshoot ``e^{−πζ/√(1−ζ²)}`` of the
    push (16.3 % for ζ = 0.5), settling on the rest."""
    robot, mass, c, inertia = _pendulum_arm(passive=True)
    zeta = 0.5
    plant = MujocoPlant(robot, [0.0, 0.0], MujocoPlantConfig(passive_damping_ratio=zeta))
    rest = plant.q[1]
    expected_rest = hanging_joints(robot, [0.0, 0.0])[1]
    assert rest == pytest.approx(expected_rest, abs=1e-9)
    # c = 2 ζ √(k I), k = m g c about the hanging rest
    assert plant.passive_damping[1] == pytest.approx(
        2 * zeta * math.sqrt(mass * G * c * inertia), rel=1e-4
    )
    for _ in range(20):
        plant.step([0.0, 0.0], 0.01)
    assert abs(plant.q[1] - rest) < 1e-7
    push = 0.05
    plant.data.qpos[plant.mj.qpos[1]] = rest + push
    x = []
    for _ in range(400):
        plant.step([0.0, 0.0], 0.01)
        x.append(plant.q[1] - rest)
    overshoot = -min(x) / push
    assert overshoot == pytest.approx(math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2)), abs=0.02)
    assert abs(x[-1]) < 1e-3 * push


# ------------------------------------------------------------------ scenarios on MuJoCo


def _check_mujoco_run(name: str) -> dict:  # type: ignore[type-arg]
    log = simulate(name, plant="mujoco")
    ref = simulate(name)
    assert log.extras["plant"] == "mujoco" and ref.extras["plant"] == "scenario"
    assert log.all_goals_reached, [g for g in log.goals if g.reached_at is None]
    assert log.first_collision is None
    assert float(log.min_distance.min()) >= 0.02
    # MuJoCo's joint limits are soft constraints: allow 1 mrad / 1 mm at an end stop
    assert all(log.limits_held(tol=1e-3).values())
    comp = plant_comparison(log, ref)
    for robot in log.robots:
        tr = log.extras["tracking"][robot]
        assert tr["ticks"] == log.t.size
        # a real dynamics run, not the kinematic integrator renamed
        assert comp["robots"][robot]["joint_difference_max"] > 1e-4
        assert all(t is not None for t in comp["robots"][robot]["goals_reached_at"])
    summary = log.summary()
    assert summary["extras"]["tracking"].keys() == set(log.robots)
    return {"log": log, "ref": ref, "comparison": comp}


@needs_mujoco
def test_p5_on_mujoco_reaches_goals_without_collision() -> None:
    run = _check_mujoco_run("p5-crane-obstacle")
    tr = run["log"].extras["tracking"]["crane"]
    # the grabber swings physically (the kinematic plant keeps it straight down) ...
    assert tr["passive_swing_max"] > 0.005
    # ... and the passive joints move on their own although never commanded
    q = run["log"].q["crane"]
    assert np.ptp(q[:, 4] - (q[:, 1] + q[:, 2])) > 1e-3


@needs_mujoco
def test_p3_on_mujoco_reaches_goals_without_collision() -> None:
    _check_mujoco_run("p3-self-collision")


# ------------------------------------------------------------------ errors and the CLI


def test_missing_extra_is_named(monkeypatch: pytest.MonkeyPatch) -> None:
    """Runs whether or not MuJoCo is installed: the import is blocked."""
    from reachwise.cli.simulate import simulate as sim_cli

    monkeypatch.setitem(sys.modules, "mujoco", None)  # import mujoco -> ImportError
    hint = r"the MuJoCo plant needs the optional package 'mujoco': pip install \"reachwise\[sim\]\""
    with pytest.raises(MissingDependency, match=hint) as info:
        require_mujoco()
    assert isinstance(info.value, ImportError)
    assert (info.value.package, info.value.extra) == ("mujoco", "sim")
    with pytest.raises(MissingDependency, match=hint):
        simulate("p5-crane-obstacle", plant="mujoco", duration=0.1)
    app = typer.Typer()
    app.command()(sim_cli)
    res = CliRunner().invoke(app, ["p5-crane-obstacle", "--plant", "mujoco"])
    assert res.exit_code != 0
    assert isinstance(res.exception, MissingDependency)
    assert 'pip install "reachwise[sim]"' in str(res.exception)


def test_bad_plant_and_config_are_input_errors() -> None:
    with pytest.raises(InputError, match="plant"):
        simulate("p5-crane-obstacle", plant="bogus", duration=0.1)
    with pytest.raises(InputError, match="servo_time_constant"):
        MujocoPlantConfig(servo_time_constant=0.0)


@needs_mujoco
def test_bad_plant_input_is_an_input_error() -> None:
    robot, _ = _turntable()
    with pytest.raises(InputError, match="q0"):
        MujocoPlant(robot, [0.0, 1.0])
    with pytest.raises(InputError, match="command"):
        MujocoPlant(robot, [0.0]).step([math.nan], 0.01)


def test_plant_config_follows_the_scenario_plant() -> None:
    hyd = MujocoPlantConfig.like(PlantConfig(kind="hydraulic", time_constant=0.08, rate_limit=1.0))
    assert (hyd.servo_time_constant, hyd.rate_limit) == (0.08, 1.0)
    kin = MujocoPlantConfig.like(PlantConfig())
    assert kin.servo_time_constant == 0.02 and math.isinf(kin.rate_limit)


@needs_mujoco
def test_cli_reports_tracking_and_comparison() -> None:
    import json

    from reachwise.cli.simulate import simulate as sim_cli

    app = typer.Typer()
    app.command()(sim_cli)
    res = CliRunner().invoke(
        app, ["p5-crane-obstacle", "--plant", "mujoco", "--duration", "2", "--json"]
    )
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert data["avoidance"]["extras"]["plant"] == "mujoco"
    assert data["reference"]["extras"]["plant"] == "scenario"
    comp = data["avoidance"]["extras"]["comparison"]["robots"]["crane"]
    assert comp["reference_min_distance"] == pytest.approx(data["reference"]["min_distance"])
    assert data["avoidance"]["extras"]["tracking"]["crane"]["ticks"] == 201
    res = CliRunner().invoke(
        app, ["p5-crane-obstacle", "--plant", "mujoco", "--duration", "1"], env={"COLUMNS": "300"}
    )
    assert res.exit_code == 0, res.output
    assert "position lag" in res.stdout and "vs scenario plant" in res.stdout
