"""``reachwise synth``: dimensional synthesis of a template robot for a task."""

from __future__ import annotations

import json
from pathlib import Path

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from reachwise.cli._robot_options import LENIENT, PACKAGE_DIRS, TIP, load_with_options


def synth(
    task: str = typer.Option(..., "--task", help="Task file or built-in task (tunnel-87)."),
    robot: str = typer.Option(..., "--robot", help="Template robot with a design section."),
    out: Path = typer.Option(..., "--out", help="Output folder."),
    runs: int = typer.Option(10, "--runs", min=1, help="Multi-start runs (own seeds)."),
    solver: str = typer.Option("dls", "--solver", help="dls (thesis) or trf (scipy)."),
    seed: int = typer.Option(0, "--seed", help="Seed of the first run; run i uses seed+i."),
    lock: list[int] = typer.Option([], "--lock", help="Lock joint variable INDEX (repeat)."),
    tunnel: bool = typer.Option(
        True, "--tunnel/--no-tunnel", help="Keep links inside the task's tunnel envelope."
    ),
    figures: bool = typer.Option(True, "--figures/--no-figures", help="Write PNG figures."),
    json_out: bool = typer.Option(False, "--json", help="Print the summary as JSON."),
    tip: str | None = TIP,
    package_dir: list[Path] = PACKAGE_DIRS,
    lenient: bool = LENIENT,
) -> None:
    """Find design parameters, base frame and joints reaching every task pose (P-I).

    Ctrl-C stops after the current run and writes the runs finished so far.
    """
    from reachwise.errors import check_choice
    from reachwise.io.synthesis_out import summary, write_synthesis
    from reachwise.io.task_file import load_task
    from reachwise.report.synthesis import save_synthesis_figures, write_synthesis_report
    from reachwise.synthesis.problem import SynthesisProblem, locked_from_spec
    from reachwise.synthesis.synthesize import SOLVERS, RunResult, result_of, run_once

    solver_name = check_choice(solver, SOLVERS, source="--solver", kind="solver")
    t = load_task(task)
    template = load_with_options(robot, tip, package_dir, lenient)
    workspace = t.envelope if tunnel else None
    problem = SynthesisProblem(template, t, locked_from_spec(template, lock or None))
    console = Console(stderr=True)
    done: list[RunResult] = []
    interrupted = False
    with Progress(
        TextColumn("[bold]synthesis"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
        TextColumn("{task.description}"), console=console, disable=json_out,
    ) as bar:  # fmt: skip
        job = bar.add_task("", total=runs)
        try:
            for i in range(runs):
                r = run_once(problem, seed + i, solver_name, workspace=workspace)
                done.append(r)
                bar.update(job, advance=1, description=f"run {i}: {r.n_reached}/{problem.K}")
        except KeyboardInterrupt:
            interrupted = True
    if not done:
        console.print("interrupted before the first run finished: nothing written")
        raise typer.Exit(130)
    result = result_of(problem, done, solver_name)
    folder = write_synthesis(result, out)
    pngs = save_synthesis_figures(result, folder) if figures else False
    report = write_synthesis_report(result, folder, pngs)
    data = summary(result)
    data["interrupted"] = interrupted
    data["out"] = str(folder)
    data["report"] = str(report)
    if json_out:
        typer.echo(json.dumps(data, indent=2))
    else:
        _print(result, data)
    if interrupted:
        raise typer.Exit(130)


def _print(result: object, data: dict) -> None:  # type: ignore[type-arg]
    from reachwise.io.synthesis_out import design_rows

    console = Console()
    b = data["best"]
    console.print(
        f"{data['template']} on {data['task']}: {data['runs_reaching_all']}/{data['runs']} runs "
        f"reach all {data['task_points']} points; best seed {data['best_seed']}: "
        f"{b['reached']} reached, e_obj {b['e_obj']:.3g}, GCI {b['gci_initial']:.3f} → "
        f"{b['gci']:.3f}, KCI {b['kci_initial']:.3f} → {b['kci']:.3f}"
    )
    t = Table(title="normalized design parameters (P-I Table 3)")
    for c in ("parameter", "initial", "optimized", "changed %"):
        t.add_column(c, justify="right")
    for row in design_rows(result):  # type: ignore[arg-type]
        t.add_row(*row)
    console.print(t)
    console.print(f"wrote {data['out']}/ (design.yaml, design.urdf, summary.json, points.csv)")
    console.print(f"report: {data['report']}")
