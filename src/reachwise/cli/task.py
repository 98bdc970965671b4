"""``reachwise task generate|show``: build tunnel drilling tasks and inspect task files.

``generate tunnel`` writes one drill plan (or, with ``--plans N``, N plans of different
sizes combined like the thesis's 10 plans, P-I §4); ``generate tunnel-87`` writes the
built-in stand-in for the thesis's 87-point task; ``show`` summarizes any task.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import typer

from reachwise.cli._help import builtins

app = typer.Typer(help="Generate drilling tasks and inspect task files.", no_args_is_help=True)
generate_app = typer.Typer(help="Generate a task file.", no_args_is_help=True)
app.add_typer(generate_app, name="generate")

_MAX_PAIRWISE = 5000


def _angle_stats(axes: Any) -> dict[str, float]:
    """Angles (deg) of unit axes ``(k, 3)`` from +x and the largest angle between two."""
    import numpy as np

    from_x = np.degrees(np.arccos(np.clip(axes[:, 0], -1.0, 1.0)))
    out = {
        "axis_angle_from_x_min_deg": float(from_x.min()),
        "axis_angle_from_x_max_deg": float(from_x.max()),
    }
    if len(axes) <= _MAX_PAIRWISE:
        cos_min = min(float((axes[i : i + 500] @ axes.T).min()) for i in range(0, len(axes), 500))
        out["axis_spread_deg"] = float(np.degrees(np.arccos(np.clip(cos_min, -1.0, 1.0))))
    return out


def task_summary(task: Any) -> dict[str, Any]:
    """Machine-readable summary of a task (what ``show --json`` prints): counts per group
    and task-space dimension, bounding box of the positions (m), spread of the tool axes
    over the points that constrain them (dims ≥ 5), tolerances and the envelope."""
    import numpy as np

    P = task.positions
    oriented = task.dims >= 5
    groups: dict[str, Any] = {}
    for g, ix in task.group_indices().items():
        entry: dict[str, Any] = {"points": len(ix)}
        sel = ix[oriented[ix]]
        if len(sel):
            entry.update(_angle_stats(task.axes[sel]))
        groups[g] = entry
    dims, counts = np.unique(task.dims, return_counts=True)
    out: dict[str, Any] = {
        "name": task.name,
        "points": len(task),
        "dims": {str(int(d)): int(c) for d, c in zip(dims, counts, strict=True)},
        "groups": groups,
        "bounding_box_m": {"min": P.min(axis=0).tolist(), "max": P.max(axis=0).tolist()},
        "tolerance": {
            "position_m": [float(task.tol_position.min()), float(task.tol_position.max())],
            "orientation_rad": [
                float(task.tol_orientation.min()),
                float(task.tol_orientation.max()),
            ],
        },
    }
    if oriented.any():
        out["axes"] = _angle_stats(task.axes[oriented])
    if task.envelope is not None:
        pr = task.envelope.profile
        sd = task.envelope.signed_distance(P)
        out["envelope"] = {
            "width_m": pr.width,
            "height_m": pr.height,
            "arch_height_m": pr.arch_height,
            "area_m2": pr.area,
            "y_center_m": pr.y_center,
            "floor_z_m": pr.floor_z,
            "face_x_m": task.envelope.face_x,
            "min_clearance_m": float(sd.min()),
        }
    return out


def _print_summary(data: dict[str, Any]) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    dims = ", ".join(f"{n} × {d}-D" for d, n in data["dims"].items())
    console.print(f"[bold]{data['name']}[/bold]: {data['points']} points ({dims})")
    t = Table()
    for col in ("group", "points", "axis from +x (deg)", "axis spread (deg)"):
        t.add_column(col)
    for g, e in data["groups"].items():
        rng = (
            f"{e['axis_angle_from_x_min_deg']:.1f} … {e['axis_angle_from_x_max_deg']:.1f}"
            if "axis_angle_from_x_min_deg" in e
            else "-"
        )
        spread = f"{e['axis_spread_deg']:.1f}" if "axis_spread_deg" in e else "-"
        t.add_row(g or "(none)", str(e["points"]), rng, spread)
    console.print(t)
    lo, hi = data["bounding_box_m"]["min"], data["bounding_box_m"]["max"]
    console.print(
        "positions: " + ", ".join(f"{a} {lo[i]:.3f} … {hi[i]:.3f} m" for i, a in enumerate("xyz"))
    )
    if "envelope" in data:
        e = data["envelope"]
        console.print(
            f"envelope: tunnel {e['width_m']:g} × {e['height_m']:g} m "
            f"(arch {e['arch_height_m']:g} m, {e['area_m2']:.1f} m²); "
            f"smallest clearance of a point {e['min_clearance_m']:.3f} m"
        )


def _write(task: Any, out: Path, json_out: bool, comment: str | None = None) -> None:
    from reachwise.io.task_file import save_task

    save_task(task, out, comment=comment)
    if json_out:
        typer.echo(json.dumps({"written": str(out), **task_summary(task)}, indent=2))
    else:
        typer.echo(f"wrote {out}: {len(task)} points")
        _print_summary(task_summary(task))


@generate_app.command("tunnel")
def generate_tunnel(
    out: Path = typer.Option(..., "--out", help="Task file to write (.yaml, .json or .csv)."),
    width: float = typer.Option(
        6.0, "--width", help="Tunnel width (m); with --plans, the largest."
    ),
    height: float = typer.Option(5.5, "--height", help="Floor to crown (m)."),
    arch: float = typer.Option(1.8, "--arch", help="Rise of the arched roof (m), ≤ width/2."),
    face_x: float | None = typer.Option(
        None, "--face-x", help="Face distance ahead of the machine (m, default 7; one plan only)."
    ),
    lookout_deg: float | None = typer.Option(
        None, "--lookout-deg", help="Contour look-out angle (deg, default 3; one plan only)."
    ),
    hole_depth: float = typer.Option(4.5, "--hole-depth", help="Hole depth (m)."),
    contour_spacing: float = typer.Option(0.7, "--contour-spacing", help="Contour spacing (m)."),
    cut: str = typer.Option("v", "--cut", help="Cut type: v (angled V-cut) or parallel."),
    dims: int = typer.Option(5, "--dims", help="5 (collar + hole axis) or 6 (+ feed roll)."),
    seed: int = typer.Option(0, "--seed", help="Seed for collar jitter and plan variation."),
    jitter: float = typer.Option(0.0, "--jitter", help="Collar jitter (m), one plan only."),
    plans: int = typer.Option(
        1, "--plans", help="Combine N plans of 20 m² up to this profile (thesis: 10)."
    ),
    points: int | None = typer.Option(
        None, "--points", help="Down-select the combined plans to this many points."
    ),
    json_out: bool = typer.Option(False, "--json", help="Print a JSON summary."),
) -> None:
    """Generate a tunnel-face drilling task (public stand-in for customer drill plans)."""
    import math

    from reachwise.errors import TaskError
    from reachwise.tasks.drilling import combine_plans, drilling_pattern, tunnel_plans
    from reachwise.tasks.workspace import TunnelEnvelope, TunnelProfile

    profile = TunnelProfile(width, height, arch)
    if plans > 1:
        if face_x is not None or lookout_deg is not None or jitter:
            raise TaskError(
                "--plans",
                "",
                "with several plans face distance, look-out and jitter are drawn "
                "per plan from --seed; drop --face-x, --lookout-deg and --jitter",
            )
        family = tunnel_plans(plans, largest=profile, seed=seed, dims=dims)
        task = combine_plans(
            family, points, name=f"tunnel-{plans}-plans", envelope=TunnelEnvelope(profile)
        )
    else:
        if points is not None:
            raise TaskError("--points", "", "down-selection needs --plans > 1")
        if cut not in ("v", "parallel"):
            raise TaskError("--cut", "", f"must be v or parallel, got {cut!r}")
        task = drilling_pattern(
            profile,
            face_x=7.0 if face_x is None else face_x,
            lookout_angle=math.radians(3.0 if lookout_deg is None else lookout_deg),
            hole_depth=hole_depth,
            contour_spacing=contour_spacing,
            cut_type="v" if cut == "v" else "parallel",
            jitter=jitter,
            seed=seed,
            dims=dims,
        )
    _write(task, out, json_out)


@generate_app.command("tunnel-87")
def generate_tunnel_87(
    out: Path = typer.Option(..., "--out", help="Task file to write (.yaml, .json or .csv)."),
    json_out: bool = typer.Option(False, "--json", help="Print a JSON summary."),
) -> None:
    """Write the built-in tunnel-87 task (10 plans → 87 points, P-I §4 stand-in)."""
    from reachwise.io.atomic import atomic_write
    from reachwise.io.task_file import builtin_task_text, load_task, save_task

    if out.suffix.lower() in (".yaml", ".yml"):
        atomic_write(out, builtin_task_text("tunnel-87"))
        task = load_task(out)
    else:
        from reachwise.tasks.drilling import tunnel_87

        task = tunnel_87()
        save_task(task, out)
    if json_out:
        typer.echo(json.dumps({"written": str(out), **task_summary(task)}, indent=2))
    else:
        typer.echo(f"wrote {out}: {len(task)} points")


@app.command("show")
def show(
    task: str = typer.Argument(
        ..., help=f"Task file (.yaml/.json/.csv) or built-in task ({builtins('tasks')})."
    ),
    json_out: bool = typer.Option(False, "--json", help="Print JSON."),
) -> None:
    """Summarize a task: points per zone and dimension, extent, spread of tool axes."""
    from reachwise.io.task_file import load_task

    data = task_summary(load_task(task))
    if json_out:
        typer.echo(json.dumps(data, indent=2))
    else:
        _print_summary(data)
