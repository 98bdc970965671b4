"""``reachwise robot show|check|export``: inspect, validate and export robot models."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import typer
from rich.console import Console
from rich.table import Table

app = typer.Typer(help="Inspect, validate and export robot models.", no_args_is_help=True)


def summary(robot: Any) -> dict[str, Any]:
    """Machine-readable description of a robot (what ``show --json`` prints)."""
    import numpy as np

    from reachwise.io.robot_file import robot_to_dict
    from reachwise.kinematics.ik import sample_configurations
    from reachwise.kinematics.indices import gci, kci, lci

    Q = sample_configurations(robot, np.random.default_rng(0), 2000)
    T = robot.fk(Q)
    reach = np.linalg.norm(T[:, :3, 3] - robot.base[:3, 3], axis=1)
    lcis = lci(robot, Q)
    data = robot_to_dict(robot)
    data["dof"] = robot.n
    data["sampled"] = {
        "configurations": int(Q.shape[0]),
        "reach_max_m": float(reach.max()),
        "reach_min_m": float(reach.min()),
        "lci_mean": gci(lcis),
        "lci_min": kci(lcis),
        "seed": 0,
    }
    return data


@app.command("show")
def show(
    robot: str = typer.Argument(..., help="Built-in name (panda, sb60, …) or YAML/URDF file."),
    json_out: bool = typer.Option(False, "--json", help="Print JSON."),
) -> None:
    """Print the DH table, limits and sampled reach/conditioning of a robot."""
    from reachwise.io.robot_file import load_robot

    r = load_robot(robot)
    data = summary(r)
    if json_out:
        typer.echo(json.dumps(data, indent=2))
        return
    t = Table(title=f"{r.name} ({r.convention} DH, {r.n} joint variables)")
    for col in ("#", "type", "a (m)", "alpha (deg)", "d (m)", "theta (deg)", "limits", "vmax"):
        t.add_column(col)
    for i, j in enumerate(r.joints):
        unit = "m" if j.type == "prismatic" else "deg"
        conv = (lambda v: v) if j.type == "prismatic" else math.degrees
        lim = f"[{conv(j.limits[0]):.4g}, {conv(j.limits[1]):.4g}] {unit}" if j.movable else ""
        vmax = f"{conv(j.vmax):.4g} {unit}/s" if j.movable and math.isfinite(j.vmax) else ""
        kind = j.type + (" (passive)" if j.passive else "")
        t.add_row(str(i), kind, f"{j.a:.4g}", f"{math.degrees(j.alpha):.4g}", f"{j.d:.4g}",
                  f"{math.degrees(j.theta):.4g}", lim, vmax)  # fmt: skip
    console = Console()
    console.print(t)
    s = data["sampled"]
    console.print(
        f"reach over {s['configurations']} random configurations: "
        f"{s['reach_min_m']:.3f} … {s['reach_max_m']:.3f} m from the base; "
        f"LCI mean {s['lci_mean']:.3f}, min {s['lci_min']:.2e}"
    )
    if r.design.size:
        free = ", ".join(r.design_names)
        console.print(f"design parameters ({r.design.size}): {free}")


@app.command("check")
def check(
    path: Path = typer.Argument(..., help="Robot file (YAML or URDF)."),
    json_out: bool = typer.Option(False, "--json", help="Print JSON."),
) -> None:
    """Validate a robot file; exit 2 with the file, field and reason if it is wrong."""
    from reachwise.errors import ReachwiseError
    from reachwise.io.robot_file import load_robot_file

    try:
        r = load_robot_file(path)
    except ReachwiseError as exc:
        if json_out:
            typer.echo(json.dumps({"ok": False, "error": str(exc)}))
        else:
            typer.secho(f"invalid: {exc}", err=True, fg=typer.colors.RED)
        raise typer.Exit(2) from None
    if json_out:
        typer.echo(json.dumps({"ok": True, "name": r.name, "dof": r.n, "joints": len(r.joints)}))
    else:
        typer.echo(f"ok: {path} defines {r.name!r}: {len(r.joints)} joints, {r.n} joint variables")


@app.command("export")
def export(
    robot: str = typer.Argument(..., help="Built-in name or robot file."),
    urdf: Path = typer.Option(..., "--urdf", help="Write a URDF file here."),
) -> None:
    """Export a robot to URDF."""
    from reachwise.io.robot_file import load_robot
    from reachwise.io.urdf import export_urdf

    export_urdf(load_robot(robot), urdf)
    typer.echo(f"wrote {urdf}")
