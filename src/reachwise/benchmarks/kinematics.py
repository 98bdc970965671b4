"""``reachwise bench kinematics``: compiled FK/Jacobians/IK against a naive numpy loop.

The baseline is the textbook implementation: one 4x4 ``numpy`` product per joint in a
Python loop, Jacobian columns by cross products, and for IK the same DLS iteration in
numpy. Both run in the same process on the same inputs.
"""

from __future__ import annotations

import numpy as np

from reachwise.benchmarks._harness import BenchReport, Target, time_calls
from reachwise.io.robot_file import load_robot
from reachwise.kinematics.jacobian import jacobians
from reachwise.kinematics.robot import Robot


def _dh(robot: Robot, j: int, qv: float) -> np.ndarray:
    jt = robot.joints[j]
    theta = jt.theta + (qv if jt.type == "revolute" else 0.0)
    d = jt.d + (qv if jt.type == "prismatic" else 0.0)
    ca, sa, ct, st = np.cos(jt.alpha), np.sin(jt.alpha), np.cos(theta), np.sin(theta)
    return np.array(
        [[ct, -st, 0, jt.a], [st * ca, ct * ca, -sa, -sa * d], [st * sa, ct * sa, ca, ca * d],
         [0, 0, 0, 1.0]]
    )  # fmt: skip


def naive_fk_jacobian(robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-joint numpy loop (modified DH): tool pose and geometric Jacobian."""
    T = robot.base.copy()
    axes = []
    k = 0
    for j, jt in enumerate(robot.joints):
        qv = q[k] if jt.movable else 0.0
        T = T @ _dh(robot, j, qv)
        if jt.movable:
            axes.append((jt.type, T[:3, 2].copy(), T[:3, 3].copy()))
            k += 1
    T = T @ robot.tool
    J = np.zeros((6, robot.n))
    for i, (kind, z, p) in enumerate(axes):
        if kind == "revolute":
            J[:3, i] = np.cross(z, T[:3, 3] - p)
            J[3:, i] = z
        else:
            J[:3, i] = z
    return T, J


def naive_ik(robot: Robot, Td: np.ndarray, q0: np.ndarray, iters: int = 100) -> np.ndarray:
    """Plain numpy DLS with a rotation-vector error, for the timing baseline."""
    from scipy.spatial.transform import Rotation

    q = q0.copy()
    for _ in range(iters):
        T, J = naive_fk_jacobian(robot, q)
        e = np.concatenate(
            [Td[:3, 3] - T[:3, 3], Rotation.from_matrix(Td[:3, :3] @ T[:3, :3].T).as_rotvec()]
        )
        if np.linalg.norm(e) < 1e-9:
            break
        dq = J.T @ np.linalg.solve(J @ J.T + 1e-6 * np.eye(6), e)
        q = np.clip(q + dq, robot.lower, robot.upper)
    return q


def run(quick: bool = False) -> BenchReport:
    rep = BenchReport("kinematics")
    rng = np.random.default_rng(0)
    reps = 300 if quick else 5000
    boom = load_robot("sb60")
    if boom.convention != "modified" or len(boom.joints) < 8:
        rep.notes.append("sb60 is not an 8-joint modified-DH chain: figures refer to it as is")
    q = rng.uniform(boom.lower, boom.upper)
    rep.add_samples(
        "reachwise.fk_jacobian_8dof", time_calls(lambda: jacobians(boom, q, False), reps)
    )
    rep.add_samples("naive.fk_jacobian_8dof", time_calls(lambda: naive_fk_jacobian(boom, q), reps))
    rep.ratio("reachwise.fk_jacobian_8dof", "naive.fk_jacobian_8dof")

    Q = rng.uniform(boom.lower, boom.upper, (87, boom.n))
    breps = reps // 5
    rep.add_samples("reachwise.fk_batch87", time_calls(lambda: boom.fk(Q), breps))
    rep.add_samples(
        "naive.fk_batch87", time_calls(lambda: [naive_fk_jacobian(boom, x) for x in Q], breps // 5)
    )
    rep.ratio("reachwise.fk_batch87", "naive.fk_batch87")
    rep.add_samples(
        "reachwise.jacobians_params_batch87", time_calls(lambda: jacobians(boom, Q, True), breps)
    )

    panda = load_robot("panda")
    targets = panda.fk(rng.uniform(panda.lower, panda.upper, (reps // 5 if quick else 1000, 7)))
    it = iter(range(10**9))
    gen = np.random.default_rng(1)

    def solve() -> None:
        panda.ik(targets[next(it) % len(targets)], rng=gen)

    ik_samples = time_calls(solve, len(targets), warmup=3)
    rep.add_samples("reachwise.ik_panda", ik_samples)
    mid = 0.5 * (panda.lower + panda.upper)
    nt = iter(range(10**9))
    rep.add_samples(
        "naive.ik_panda",
        time_calls(lambda: naive_ik(panda, targets[next(nt) % len(targets)], mid), 50, warmup=2),
    )
    rep.ratio("reachwise.ik_panda", "naive.ik_panda")
    m = rep.metrics
    rep.targets["fk_jacobian_8dof_median_us"] = Target(m["reachwise.fk_jacobian_8dof.median"], 20)
    rep.targets["fk_batch87_median_us"] = Target(m["reachwise.fk_batch87.median"], 100)
    rep.targets["jacobians_params_batch87_median_us"] = Target(
        m["reachwise.jacobians_params_batch87.median"], 1000
    )
    rep.targets["ik_panda_median_us"] = Target(m["reachwise.ik_panda.median"], 1000)
    rep.notes.append(
        "naive.ik_panda is one plain numpy DLS attempt from mid-range (no restarts); "
        "reachwise.ik_panda includes restarts until success"
    )
    return rep
