"""``reachwise demo``: the main job on embedded defaults.

Everything it prints is computed on the spot from the built-in robots, tasks and
scenes: inverse kinematics and conditioning of the built-in robots, the dimensional
synthesis of the SB60-like boom for the 87-point tunnel task (P-I), and exact
distance queries between a boom part and the scanned P-V floor obstacle. Later stages
(topology sweep, the thesis's collision-avoidance experiments, the HTML report) join
it as they land.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import typer
from rich.console import Console
from rich.table import Table


def demo(
    out: Path = typer.Option(Path("reachwise-demo"), "--out", help="Folder for the results."),
    runs: int = typer.Option(3, "--runs", min=1, help="Synthesis runs (multi-start)."),
    seed: int = typer.Option(0, help="Seed of every random draw."),
    json_out: bool = typer.Option(False, "--json", help="Print the key figures as JSON."),
) -> None:
    """Run the main job on built-in defaults, print the key figures, write results."""
    console = Console(quiet=json_out)
    out.mkdir(parents=True, exist_ok=True)
    figures: dict[str, Any] = {"seed": seed, "out": str(out.resolve())}
    t0 = time.perf_counter()
    figures["kinematics"] = _kinematics(console, seed)
    figures["synthesis"] = _synthesis(console, out / "synthesis-sb60-tunnel-87", runs, seed)
    figures["distance"] = _distance(console, seed)
    figures["elapsed_s"] = time.perf_counter() - t0
    (out / "demo.json").write_text(json.dumps(figures, indent=2))
    console.rule()
    console.print(f"done in {figures['elapsed_s']:.1f} s; results in {out.resolve()}/")
    if json_out:
        typer.echo(json.dumps(figures, indent=2))


def _kinematics(console: Console, seed: int) -> dict[str, Any]:
    from reachwise.io.robot_file import load_robot
    from reachwise.kinematics.indices import lci

    console.rule("1. kinematics of the built-in robots")
    rng = np.random.default_rng(seed)
    table = Table(title="IK of 50 random reachable targets per robot (tolerance 1 µm, 1 µrad)")
    for col in ("robot", "DOF", "task", "solved", "worst error m / rad", "IK ms", "LCI mean / min"):
        table.add_column(col, justify="right")
    rows: dict[str, Any] = {}
    for name in ("panda", "puma560", "sb60", "hiab-xs033"):
        robot = load_robot(name)
        m = 50
        Q = rng.uniform(robot.lower, robot.upper, (m, robot.n))
        mask = None if robot.actuated.sum() >= 6 else 3
        solved, ep, eo, times = 0, 0.0, 0.0, []
        for T in robot.fk(Q):
            t = time.perf_counter()
            res = robot.ik(T, mask=mask, rng=rng)
            times.append(time.perf_counter() - t)
            solved += res.success
            ep, eo = max(ep, res.position_error), max(eo, res.orientation_error)
        lcis = np.asarray(lci(robot, Q, rows=None if mask is None else [0, 1, 2]))
        row = {
            "dof": robot.n,
            "task_dims": 6 if mask is None else 3,
            "targets": m,
            "solved": solved,
            "max_position_error_m": ep,
            "max_orientation_error_rad": eo,
            "median_ik_ms": float(np.median(times) * 1e3),
            "lci_mean": float(lcis.mean()),
            "lci_min": float(lcis.min()),
        }
        rows[name] = row
        cond = f"{row['lci_mean']:.3f} / {row['lci_min']:.0e}"
        table.add_row(name, str(robot.n), f"{row['task_dims']}-D", f"{solved}/{m}",
                      f"{ep:.0e} / {eo:.0e}", f"{row['median_ik_ms']:.2f}", cond)  # fmt: skip
    console.print(table)
    return rows


def _synthesis(console: Console, folder: Path, runs: int, seed: int) -> dict[str, Any]:
    from reachwise.io.synthesis_out import design_rows, summary, write_synthesis
    from reachwise.io.task_file import load_task
    from reachwise.synthesis.synthesize import synthesize

    console.rule("2. dimensional synthesis: sb60 boom for the tunnel-87 task (P-I)")
    task = load_task("tunnel-87")
    t = time.perf_counter()
    with console.status(f"synthesizing {runs} runs …"):
        result = synthesize(task, "sb60", runs=runs, seed=seed)
    elapsed = time.perf_counter() - t
    write_synthesis(result, folder)
    data = summary(result)
    b = data["best"]
    console.print(
        f"{data['task_points']} task points, {data['unknowns']} unknowns, "
        f"{data['residuals']} residuals; {data['runs_reaching_all']}/{data['runs']} runs "
        f"reach every point inside the tunnel ({elapsed:.1f} s)"
    )
    console.print(
        f"best run: {b['reached']}/{data['task_points']} points within 1 mm / 1 mrad, "
        f"GCI {b['gci_initial']:.3f} → {b['gci']:.3f}, KCI {b['kci_initial']:.3f} → "
        f"{b['kci']:.3f}"
    )
    table = Table(title="normalized design parameters (P-I Table 3)")
    for c in ("parameter", "initial", "optimized", "changed %"):
        table.add_column(c, justify="right")
    for row in design_rows(result):
        table.add_row(*row)
    console.print(table)
    console.print(f"wrote {folder}/ (design.yaml, design.urdf, summary.json, points.csv, PNGs)")
    return {
        "runs": data["runs"],
        "runs_reaching_all": data["runs_reaching_all"],
        "best": b,
        "elapsed_s": elapsed,
        "folder": str(folder),
    }


def _distance(console: Console, seed: int) -> dict[str, Any]:
    from reachwise.distance import PairQuery, closest_points
    from reachwise.geometry.cloud import sample_mesh_surface
    from reachwise.geometry.scanner import scan_scene
    from reachwise.kinematics.transforms import pose_from_xyz_rpy

    console.rule("3. exact point-cloud distances (P-V scan, thesis §3.1)")
    _, env = scan_scene("p5-floor-obstacle", np.random.default_rng(seed))
    import trimesh

    part = sample_mesh_surface(trimesh.creation.box((0.6, 0.4, 0.3)), n=1000, seed=seed)
    rng = np.random.default_rng(seed)
    query = PairQuery(part, env, margin=0.5)
    lo, hi = env.bounds
    agree, times, at_risk = 0, [], 0
    m = 200
    for _ in range(m):
        xyz = rng.uniform(lo, hi) + np.array([0.0, 0.0, rng.uniform(0.2, 1.0)])
        pose = pose_from_xyz_rpy(xyz, rng.uniform(-np.pi, np.pi, 3))
        t = time.perf_counter()
        fast = query(pose_a=pose)
        times.append(time.perf_counter() - t)
        ref = closest_points(part, env, pose_a=pose, margin=0.5, strategy="brute")
        at_risk += not ref.no_risk
        same = fast.no_risk == ref.no_risk and (
            fast.no_risk or abs(fast.distance - ref.distance) <= 1e-9
        )
        agree += same
    med = float(np.median(times) * 1e6)
    console.print(
        f"scan: {len(env)} points (floor + obstacle, with the occlusion gap); part: "
        f"{len(part)} points; {m} random poses, margin 0.5 m: {at_risk} within the margin"
    )
    console.print(
        f"default strategy equals brute force on {agree}/{m} queries; median query {med:.0f} µs"
    )
    return {"scan_points": len(env), "queries": m, "within_margin": at_risk,
            "agree_with_brute": agree, "median_query_us": med}  # fmt: skip
