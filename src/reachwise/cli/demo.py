"""``reachwise demo``: the main job on embedded defaults.

What it runs is real computation on the built-in robots; it grows as reachwise does
(synthesis, sweeps and the thesis experiments join it as they land).
"""

from __future__ import annotations

import json
import time

import numpy as np
import typer
from rich.console import Console
from rich.table import Table


def demo(
    json_out: bool = typer.Option(False, "--json", help="Print the key figures as JSON."),
    seed: int = typer.Option(0, help="Seed of every random draw."),
) -> None:
    """Run the main job on built-in defaults and print the key figures."""
    from reachwise.io.robot_file import builtin_robots, load_robot
    from reachwise.kinematics.indices import lci

    console = Console(quiet=json_out)
    rng = np.random.default_rng(seed)
    out: dict[str, object] = {"seed": seed, "robots": {}}
    console.rule("reachwise demo: kinematics of the built-in robots")
    t = Table(title="IK of 50 random reachable targets per robot (tolerance 1 µm, 1 µrad)")
    for col in ("robot", "DOF", "solved", "worst error m / rad", "IK ms", "LCI mean / min"):
        t.add_column(col, justify="right")
    for name in ("panda", "puma560", "sb60", "hiab-xs033"):
        if name not in builtin_robots():
            continue
        robot = load_robot(name)
        m = 50
        Q = rng.uniform(robot.lower, robot.upper, (m, robot.n))
        mask = None if robot.n >= 6 else 3
        solved, ep, eo, times = 0, 0.0, 0.0, []
        for T in robot.fk(Q):
            t0 = time.perf_counter()
            res = robot.ik(T, mask=mask, rng=rng)
            times.append(time.perf_counter() - t0)
            solved += res.success
            ep, eo = max(ep, res.position_error), max(eo, res.orientation_error)
        lcis = np.asarray(lci(robot, Q))
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
        out["robots"][name] = row  # type: ignore[index]
        ik_ms = f"{row['median_ik_ms']:.2f}"
        cond = f"{row['lci_mean']:.3f} / {row['lci_min']:.0e}"
        t.add_row(name, str(robot.n), f"{solved}/{m}", f"{ep:.0e} / {eo:.0e}", ik_ms, cond)
    console.print(t)
    if json_out:
        typer.echo(json.dumps(out, indent=2))
