"""``reachwise task generate|show``: build tunnel drilling tasks and inspect task files.

``generate tunnel`` writes one drill plan (or, with ``--plans N``, N plans of different
sizes combined like the thesis's 10 plans, P-I §4); ``generate tunnel-87`` writes the
built-in stand-in for the thesis's 87-point task; ``show`` summarizes any task.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import typer

from reachwise.cli._help import builtins
from reachwise.cli._options import cli, typed_command

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


@dataclass(frozen=True)
class TunnelShape:
    """The tunnel's profile: ``width`` (m; with several plans the largest), floor to
    crown ``height`` (m) and the arched roof's rise ``arch`` (m, at most width / 2)."""

    #: Tunnel width (m).
    width: float = cli(
        typer.Option(6.0, "--width", help="Tunnel width (m); with --plans, the largest.")
    )
    #: Floor to crown (m).
    height: float = cli(typer.Option(5.5, "--height", help="Floor to crown (m)."))
    #: Rise of the arched roof (m).
    arch: float = cli(typer.Option(1.8, "--arch", help="Rise of the arched roof (m), ≤ width/2."))


@dataclass(frozen=True)
class DrillPlan:
    """One drill plan's settings: the face distance ``face_x`` (m) and contour
    look-out ``lookout_deg`` (deg; ``None``: 7 m and 3 deg), ``hole_depth`` (m),
    ``contour_spacing`` (m), the ``cut`` (``v`` or ``parallel``), the pose ``dims``
    (5 or 6), the ``seed`` and the collar ``jitter`` (m)."""

    #: Face distance ahead of the machine (m); ``None``: 7 m.
    face_x: float | None = cli(
        typer.Option(
            None,
            "--face-x",
            help="Face distance ahead of the machine (m, default 7; one plan only).",
        )
    )
    #: Contour look-out angle (deg); ``None``: 3 deg.
    lookout_deg: float | None = cli(
        typer.Option(
            None, "--lookout-deg", help="Contour look-out angle (deg, default 3; one plan only)."
        )
    )
    #: Hole depth (m).
    hole_depth: float = cli(typer.Option(4.5, "--hole-depth", help="Hole depth (m)."))
    #: Contour spacing (m).
    contour_spacing: float = cli(
        typer.Option(0.7, "--contour-spacing", help="Contour spacing (m).")
    )
    #: Cut type: v or parallel.
    cut: str = cli(typer.Option("v", "--cut", help="Cut type: v (angled V-cut) or parallel."))
    #: Pose dimensions: 5 or 6.
    dims: int = cli(typer.Option(5, "--dims", help="5 (collar + hole axis) or 6 (+ feed roll)."))
    #: Seed of the collar jitter and the plan variation.
    seed: int = cli(typer.Option(0, "--seed", help="Seed for collar jitter and plan variation."))
    #: Collar jitter (m).
    jitter: float = cli(typer.Option(0.0, "--jitter", help="Collar jitter (m), one plan only."))


@dataclass(frozen=True)
class PlanFamily:
    """Several plans combined: ``plans`` plans of 20 m² up to the profile (1: one
    plan), down-selected to ``points`` points (``None``: all)."""

    #: Plans combined (1: one plan).
    plans: int = cli(
        typer.Option(1, "--plans", help="Combine N plans of 20 m² up to this profile (thesis: 10).")
    )
    #: Points kept by down-selection; ``None``: all.
    points: int | None = cli(
        typer.Option(None, "--points", help="Down-select the combined plans to this many points.")
    )


@dataclass(frozen=True)
class TaskOutput:
    """Where the task goes: the file ``out`` and a JSON summary on stdout
    (``json_out``)."""

    #: Task file to write (.yaml, .json or .csv).
    out: Path = cli(typer.Option(..., "--out", help="Task file to write (.yaml, .json or .csv)."))
    #: Print a JSON summary.
    json_out: bool = cli(typer.Option(False, "--json", help="Print a JSON summary."))


@generate_app.command("tunnel")
@typed_command(
    order=(
        "out",
        "width",
        "height",
        "arch",
        "face_x",
        "lookout_deg",
        "hole_depth",
        "contour_spacing",
        "cut",
        "dims",
        "seed",
        "jitter",
        "plans",
        "points",
        "json_out",
    )
)
def generate_tunnel(
    shape: TunnelShape, plan: DrillPlan, family: PlanFamily, output: TaskOutput
) -> None:
    """Generate a tunnel-face drilling task (public stand-in for customer drill plans)."""
    import math

    from reachwise.errors import TaskError
    from reachwise.tasks.drilling import combine_plans, drilling_pattern, tunnel_plans
    from reachwise.tasks.workspace import TunnelEnvelope, TunnelProfile

    profile = TunnelProfile(shape.width, shape.height, shape.arch)
    if family.plans > 1:
        if plan.face_x is not None or plan.lookout_deg is not None or plan.jitter:
            raise TaskError(
                "--plans",
                "",
                "with several plans face distance, look-out and jitter are drawn "
                "per plan from --seed; drop --face-x, --lookout-deg and --jitter",
            )
        plans = tunnel_plans(family.plans, largest=profile, seed=plan.seed, dims=plan.dims)
        task = combine_plans(
            plans,
            family.points,
            name=f"tunnel-{family.plans}-plans",
            envelope=TunnelEnvelope(profile),
        )
    else:
        if family.points is not None:
            raise TaskError("--points", "", "down-selection needs --plans > 1")
        if plan.cut not in ("v", "parallel"):
            raise TaskError("--cut", "", f"must be v or parallel, got {plan.cut!r}")
        task = drilling_pattern(
            profile,
            face_x=7.0 if plan.face_x is None else plan.face_x,
            lookout_angle=math.radians(3.0 if plan.lookout_deg is None else plan.lookout_deg),
            hole_depth=plan.hole_depth,
            contour_spacing=plan.contour_spacing,
            cut_type="v" if plan.cut == "v" else "parallel",
            jitter=plan.jitter,
            seed=plan.seed,
            dims=plan.dims,
        )
    _write(task, output.out, output.json_out)


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
