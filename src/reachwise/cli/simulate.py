"""``reachwise simulate``: run a scenario (built-in or file), write logs and figures."""

from __future__ import annotations

import json
from pathlib import Path

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TaskID, TextColumn, TimeElapsedColumn


def simulate(
    scenario: str = typer.Argument(
        ...,
        help="Built-in scenario (p3-self-collision, p4-dual-drilling, p5-crane-obstacle) "
        "or a scenario YAML file.",
    ),
    baseline: bool = typer.Option(
        False, "--baseline", help="Also run the same controller without avoidance."
    ),
    out: Path | None = typer.Option(
        None, "--out", help="Folder for log.npz, log.csv, summary.json and figures."
    ),
    duration: float | None = typer.Option(None, "--duration", min=0.0, help="Override (s)."),
    figures: bool = typer.Option(True, "--figures/--no-figures", help="Write PNG figures."),
    json_out: bool = typer.Option(False, "--json", help="Print the summary as JSON."),
) -> None:
    """Simulate a scenario with collision avoidance (thesis §3.3, P-III/P-IV/P-V)."""
    from reachwise.sim.scenarios import load_scenario
    from reachwise.sim.simulate import SimulationLog, build_world
    from reachwise.sim.simulate import simulate as run

    sc = load_scenario(scenario)
    console = Console(stderr=True)
    logs: dict[str, SimulationLog] = {}
    modes = [True, False] if baseline else [True]
    total = duration if duration is not None else sc.spec.duration
    with Progress(
        TextColumn("[bold]{task.description}"), BarColumn(), TextColumn("{task.fields[t]}"),
        TimeElapsedColumn(), console=console, disable=json_out,
    ) as bar:  # fmt: skip
        for avoid in modes:
            label = "avoidance" if avoid else "baseline"
            job = bar.add_task(f"{sc.name} {label}", total=total, t="")

            def tick(t: float, end: float, job: TaskID = job) -> None:
                if round(t / sc.spec.dt) % 10 == 0:
                    bar.update(job, completed=min(t, end), t=f"{t:6.2f} s")

            logs[label] = run(sc, avoidance=avoid, duration=duration, progress=tick)
            bar.update(job, completed=total)
    main = logs["avoidance"]
    base = logs.get("baseline")
    data = {"avoidance": main.summary()}
    if base is not None:
        data["baseline"] = base.summary()
    if out is not None:
        main.save(out / "avoidance")
        if base is not None:
            base.save(out / "baseline")
        if figures:
            from reachwise.viz.sim_plots import save_figures

            cloud = None
            world = build_world(sc)
            objs = [o for o in world.scene.objects.values() if "/" not in o.name]
            if objs:
                import numpy as np

                poses = world.scene.poses()
                cloud = np.concatenate(
                    [o.cloud.points @ poses[o.name][:3, :3].T + poses[o.name][:3, 3] for o in objs]
                )
            save_figures(out, main, base, cloud)
        (out / "summary.json").write_text(json.dumps(data, indent=2))
        data["out"] = str(out)  # type: ignore[assignment]
    if json_out:
        typer.echo(json.dumps(data, indent=2))
        return
    _print(data, console)


def _print(data: dict, console: Console) -> None:  # type: ignore[type-arg]
    out = Console()
    for label in ("avoidance", "baseline"):
        s = data.get(label)
        if s is None:
            continue
        n_reached = sum(g["reached_at"] is not None for g in s["goals"])
        md = s["min_distance"]
        md_s = f"{md * 100:.1f} cm" if md is not None else "n/a"
        coll = s["first_collision"]
        coll_s = (
            f"collides at {coll:.2f} s ({s['first_collision_pair']})"
            if coll is not None
            else "no collision"
        )
        out.print(
            f"[bold]{label}[/]: goals reached {n_reached}"
            f"/{len(s['goals'])}, min distance {md_s}, {coll_s}, limits held "
            f"{all(s['limits_held'].values())}, speeds held {all(s['speeds_held'].values())}"
        )
        for g in s["goals"]:
            at = f"{g['reached_at']:.2f} s" if g["reached_at"] is not None else "not reached"
            out.print(f"  {g['robot']}: {g['name']}: {at}")
        for st in s["stalls"]:
            out.print(f"  stalled at {st['t']:.2f} s ({st['robot']}): {st['text']}")
    if "out" in data:
        out.print(f"wrote {data['out']}/")
