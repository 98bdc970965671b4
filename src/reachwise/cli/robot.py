"""``reachwise robot show|check|export|pairs``: inspect, validate and export robot models,
and pick their self-collision pairs."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import typer
from rich.console import Console
from rich.table import Table

from reachwise.cli._help import builtins
from reachwise.cli._options import cli, typed_command
from reachwise.cli._robot_options import (
    LENIENT,
    PACKAGE_DIRS,
    TIP,
    RobotFileOptions,
    load_with_options,
)

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
    robot: str = typer.Argument(
        ..., help=f"Built-in robot ({builtins('robots')}) or YAML/URDF file."
    ),
    json_out: bool = typer.Option(False, "--json", help="Print JSON."),
    tip: str | None = TIP,
    package_dir: list[Path] = PACKAGE_DIRS,
    lenient: bool = LENIENT,
) -> None:
    """Print the DH table, limits and sampled reach/conditioning of a robot."""
    r = load_with_options(robot, tip, package_dir, lenient)
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
    tip: str | None = TIP,
    package_dir: list[Path] = PACKAGE_DIRS,
    lenient: bool = LENIENT,
) -> None:
    """Validate a robot file; exit 2 with the file, element and reason if it is wrong.

    Every number reachwise takes from the file is checked, every mesh URI resolved."""
    from reachwise.errors import ReachwiseError
    from reachwise.io.robot_file import load_robot_file

    try:
        r = load_robot_file(path, tip=tip, package_dirs=package_dir or None, lenient=lenient)
    except ReachwiseError as exc:
        if json_out:
            typer.echo(json.dumps({"ok": False, "error": str(exc)}))
        else:
            typer.secho(f"invalid: {exc}", err=True, fg=typer.colors.RED)
        raise typer.Exit(2) from None
    shapes = sum(len(g) for g in r.geometry.values())
    if json_out:
        typer.echo(
            json.dumps(
                {"ok": True, "name": r.name, "dof": r.n, "joints": len(r.joints), "shapes": shapes}
            )
        )
    else:
        typer.echo(
            f"ok: {path} defines {r.name!r}: {len(r.joints)} joints, {r.n} joint variables, "
            f"{shapes} collision shapes on {len(r.geometry)} links"
        )


@app.command("export")
def export(
    robot: str = typer.Argument(..., help=f"Built-in robot ({builtins('robots')}) or robot file."),
    urdf: Path = typer.Option(..., "--urdf", help="Write a URDF file here."),
    tip: str | None = TIP,
    package_dir: list[Path] = PACKAGE_DIRS,
    lenient: bool = LENIENT,
) -> None:
    """Export a robot to URDF."""
    from reachwise.io.urdf import export_urdf

    export_urdf(load_with_options(robot, tip, package_dir, lenient), urdf)
    typer.echo(f"wrote {urdf}")


@dataclass(frozen=True)
class PairSearch:
    """How the pairs are picked: the ``robot`` (built-in name or file), ``samples``
    random joint vectors from ``seed``, the ``margin`` (m) that counts as close, and
    the link clouds: ``points`` sampled each, or covering their shapes within
    ``resolution`` (m); ``None``: the robot's default."""

    #: Built-in robot name or robot file (YAML or URDF).
    robot: str = cli(
        typer.Argument(
            ..., help=f"Built-in robot ({builtins('robots')}) or robot file (YAML or URDF)."
        )
    )
    #: Random joint vectors inside the limits.
    samples: int = cli(
        typer.Option(10_000, "--samples", min=1, help="Random joint vectors inside the limits.")
    )
    #: A pair closer than this counts as close (m).
    margin: float = cli(
        typer.Option(0.05, "--margin", min=0.0, help="m: a pair closer than this counts as close.")
    )
    #: Points per link cloud; ``None``: by --resolution.
    points: int | None = cli(
        typer.Option(
            None,
            "--points",
            min=1,
            help="Points per link cloud, sampled (instead of --resolution).",
        )
    )
    #: Link clouds cover their shapes within this (m); ``None``: the default.
    resolution: float | None = cli(
        typer.Option(
            None,
            "--resolution",
            min=0.0,
            help="m: link clouds that cover their shapes within this (default: 0.01 for a URDF "
            "robot; a YAML robot's own counts).",
        )
    )
    #: Seed of the random configurations.
    seed: int = cli(typer.Option(0, "--seed", help="Seed of the random configurations."))


@dataclass(frozen=True)
class PairOutput:
    """Where the pairs go: the pair file ``out``, MoveIt's SRDF ``srdf`` (``None``:
    none) and JSON on stdout (``json_out``)."""

    #: Pair file (YAML).
    out: Path = cli(typer.Option(..., "--out", help="Write the pair file (YAML) here."))
    #: SRDF file of the excluded pairs; ``None``: none.
    srdf: Path | None = cli(
        typer.Option(
            None, "--srdf", help="Also write the excluded pairs as MoveIt SRDF disable_collisions."
        )
    )
    #: Print JSON.
    json_out: bool = cli(typer.Option(False, "--json", help="Print JSON."))


@app.command("pairs")
@typed_command(
    order=(
        "robot",
        "out",
        "samples",
        "margin",
        "points",
        "resolution",
        "seed",
        "srdf",
        "json_out",
        "tip",
        "package_dir",
        "lenient",
    )
)
def pairs(search: PairSearch, output: PairOutput, robot_file: RobotFileOptions) -> None:
    """Pick a robot's self-collision pairs (MoveIt Setup Assistant method, exact distances).

    Adjacent links are excluded; pairs within the margin at the home configuration (0,
    moved into the limits) are kept and listed for review; pairs within the margin in
    at least 95 % of the random configurations (structurally close) are excluded, or
    watched with a smaller margin of their own when their clouds come within their
    resolutions (they may touch); pairs never within it are excluded; the rest are
    watched. Distances are conservative by the clouds' resolutions. The
    file lists the rule behind each exclusion. Use it in a scenario with
    ``watch: [{self: {robot: NAME, pairs: auto}, margin: …}]``."""
    import time

    from reachwise.distance.self_pairs import self_collision_pairs
    from reachwise.io.pairs_file import save_pairs
    from reachwise.io.robot_clouds import link_clouds

    robot, points, resolution, margin = (
        search.robot,
        search.points,
        search.resolution,
        search.margin,
    )
    out, srdf = output.out, output.srdf
    r = robot_file.load(robot)
    if points is not None and resolution is not None:
        raise typer.BadParameter("give --points or --resolution, not both")
    clouds = link_clouds(r, points, resolution=resolution)
    if len(clouds) < 2:
        raise typer.BadParameter(f"{robot} has {len(clouds)} link(s) with shapes; pairs need two")
    t0 = time.perf_counter()
    found = self_collision_pairs(r, clouds, margin, samples=search.samples, seed=search.seed)
    took = time.perf_counter() - t0
    save_pairs(found, out, source=r.source or robot)
    if srdf is not None:
        from reachwise.io.srdf import write_srdf

        write_srdf(found, srdf)
    rules: dict[str, int] = {}
    for p in found.excluded:
        rules[p.rule] = rules.get(p.rule, 0) + 1
    data = {
        "robot": r.name,
        "out": str(out),
        "links": len(clouds),
        "pairs": len(found.pairs),
        "watched": len(found.watched),
        "excluded": rules,
        "review": [[p.a, p.b, p.home_distance] for p in found.review],
        "own_margins": [[p.a, p.b, p.margin] for p in found.pairs if p.margin is not None],
        "samples": found.samples,
        "seconds": round(took, 3),
        "srdf": None if srdf is None else str(srdf),
    }
    if output.json_out:
        typer.echo(json.dumps(data, indent=2))
        return
    excl = ", ".join(f"{n} {rule}" for rule, n in rules.items()) or "none"
    typer.echo(
        f"{r.name}: {len(clouds)} links with shapes, {len(found.pairs)} pairs: "
        f"{len(found.watched)} watched, excluded {excl} "
        f"({found.samples} random configurations, {took:.1f} s); wrote {out}"
    )
    for p in found.review:
        typer.echo(
            f"  review: {p.a} - {p.b} is {p.home_distance * 100:.1f} cm apart at home "
            f"(margin {found.margins[(p.a, p.b)] * 100:.1f} cm): watched; check whether they "
            "touch by design"
        )
    for p in found.pairs:
        if p.margin is not None:
            typer.echo(f"  own margin: {p.a} - {p.b} {p.margin * 100:.1f} cm, {p.detail}")
    for p in found.always:
        typer.echo(f"  always: {p.a} - {p.b} excluded, {p.detail}")
