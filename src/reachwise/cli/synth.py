"""``reachwise synth``: dimensional synthesis of a template robot for a task."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from reachwise.cli._help import builtins
from reachwise.cli._options import cli, typed_command
from reachwise.cli._robot_options import RobotFileOptions

if TYPE_CHECKING:
    from reachwise.cli.interrupts import Interrupts
    from reachwise.synthesis.pareto import ParetoProgress


@dataclass(frozen=True)
class DesignProblem:
    """The synthesis problem: the ``task`` and the template ``robot`` (files or
    built-in names), the joint variables locked (``lock``, indices), the tunnel
    envelope kept (``tunnel``), the shortest free a, d (``min_length``, m) and the
    bodies' clearance (``clearance``, m; ``None``: the robot file's)."""

    #: Task file or built-in task name.
    task: str = cli(
        typer.Option(..., "--task", help=f"Task file or built-in task ({builtins('tasks')}).")
    )
    #: Template robot with a design section.
    robot: str = cli(typer.Option(..., "--robot", help="Template robot with a design section."))
    #: Joint variable indices locked.
    lock: list[int] = cli(typer.Option([], "--lock", help="Lock joint variable INDEX (repeat)."))
    #: Keep links inside the task's tunnel envelope.
    tunnel: bool = cli(
        typer.Option(
            True, "--tunnel/--no-tunnel", help="Keep links inside the task's tunnel envelope."
        )
    )
    #: Every free a, d at least this long (m); ``None``: the robot file's.
    min_length: float | None = cli(
        typer.Option(
            None,
            "--min-length",
            min=0.0,
            help="Every free a, d at least this long (m); overrides design.min_length.",
        )
    )
    #: Bodies kept this far apart and from the tunnel (m); ``None``: the robot file's.
    clearance: float | None = cli(
        typer.Option(
            None,
            "--clearance",
            min=0.0,
            help="Keep the robot file's design bodies at least this far apart and from the "
            "tunnel at every pose (m; 0: off); overrides design.clearance.",
        )
    )


@dataclass(frozen=True)
class MultiStart:
    """The solves: ``runs`` multi-start runs with ``solver`` (``dls`` or ``trf``), run
    i seeded ``seed + i``, each with bodies solving up to ``clearance_starts`` times."""

    #: Multi-start runs.
    runs: int = cli(typer.Option(10, "--runs", min=1, help="Multi-start runs (own seeds)."))
    #: dls (thesis) or trf (scipy).
    solver: str = cli(typer.Option("dls", "--solver", help="dls (thesis) or trf (scipy)."))
    #: Seed of the first run; run i uses seed + i.
    seed: int = cli(typer.Option(0, "--seed", help="Seed of the first run; run i uses seed+i."))
    #: Solves per clearance run (``SolverOptions.clearance_starts``).
    clearance_starts: int = cli(
        typer.Option(
            1,
            "--clearance-starts",
            min=1,
            help="Solves per run with --clearance while none converges: the first from the "
            "reach-only start, the others from starts that pick each pose's IK branch by "
            "its bodies; the run keeps the one serving most poses.",
        )
    )


@dataclass(frozen=True)
class DesignObjective:
    """After reach: the weighted ``objective`` to improve (``None``: the robot file's)
    and the indices it must ``keep``, or the two objectives of a ``pareto`` sweep over
    ``points`` weightings."""

    #: Weighted objectives, e.g. gci:1,size:0.2; ``None``: the robot file's.
    objective: str | None = cli(
        typer.Option(
            None,
            "--objective",
            help="After reach, improve the design: weighted objectives, e.g. gci:1,size:0.2 "
            "(gci, kci, size, limits, bounds, clearance). Default: the robot file's "
            "design.objective.",
        )
    )
    #: Indices the improvement must not make worse; ``None``: kci when gci is weighted.
    keep: str | None = cli(
        typer.Option(
            None,
            "--keep",
            help="Indices the improvement must not make worse than the reach-only design's, "
            "e.g. kci,clearance (none: nothing). Default: kci when gci is weighted.",
        )
    )
    #: Two objectives of a Pareto sweep, e.g. gci,size; ``None``: none.
    pareto: str | None = cli(
        typer.Option(
            None,
            "--pareto",
            help="Two objectives, e.g. gci,size or clearance,size: sweep their weights from "
            "the best reach-only design and keep the non-dominated designs (pareto/).",
        )
    )
    #: Weightings of the Pareto sweep.
    points: int = cli(typer.Option(8, "--points", min=2, help="Weightings of the --pareto sweep."))
    #: The clearance every design of the sweep keeps (m); ``None``: ``--clearance``.
    front_clearance: float | None = cli(
        typer.Option(
            None,
            "--front-clearance",
            help="Clearance every --pareto design keeps (m, > 0, at most --clearance; "
            "default: --clearance). The sweep starts from a run solved at --clearance; "
            "a lower value gives it room to trade clearance both ways.",
        )
    )


@dataclass(frozen=True)
class SynthesisOutput:
    """Where the result goes: the ``out`` folder, PNG ``figures`` and JSON on stdout
    (``json_out``) instead of tables."""

    #: Output folder.
    out: Path = cli(typer.Option(..., "--out", help="Output folder."))
    #: Write PNG figures.
    figures: bool = cli(typer.Option(True, "--figures/--no-figures", help="Write PNG figures."))
    #: Print the summary as JSON.
    json_out: bool = cli(typer.Option(False, "--json", help="Print the summary as JSON."))


@typed_command(
    order=(
        "task",
        "robot",
        "out",
        "runs",
        "solver",
        "seed",
        "clearance_starts",
        "lock",
        "tunnel",
        "figures",
        "objective",
        "keep",
        "pareto",
        "points",
        "front_clearance",
        "min_length",
        "clearance",
        "json_out",
        "tip",
        "package_dir",
        "lenient",
    )
)
def synth(
    design: DesignProblem, starts: MultiStart, goal: DesignObjective, output: SynthesisOutput,
    robot_file: RobotFileOptions,
) -> None:  # fmt: skip
    """Find design parameters, base frame and joints reaching every task pose (P-I),
    then, with --objective, the best reaching design (or a Pareto front, --pareto).

    Ctrl-C (once or more) ends the current run, writes the runs finished before it and
    exits with 130; during --pareto it ends the sweep and keeps the runs' files and
    the designs the sweep found, marked as a partial front.
    --pareto with no run that reaches every pose writes the runs, says why no front
    was made (the poses the best run missed) and exits with 1.
    """
    from reachwise.cli.interrupts import deferred_interrupts

    with deferred_interrupts() as interrupts:
        from reachwise.errors import check_choice
        from reachwise.synthesis.synthesize import SOLVERS

        solver_name = check_choice(starts.solver, SOLVERS, source="--solver", kind="solver")
        if goal.pareto is not None and goal.objective is not None:
            raise typer.BadParameter("give --objective or --pareto, not both")
        names = _pareto_names(goal.pareto) if goal.pareto is not None else None
        kept = _keep_names(goal.keep)
        problem, weights, workspace, bodies = _problem(
            design, robot_file, goal.objective, "clearance" in (*(names or ()), *(kept or ()))
        )
        if names is not None:
            weights = {}  # the sweep starts from the reach-only design
        front_bodies = _front_bodies(goal, names, bodies[0])
        done = _runs(
            problem, starts, solver_name, workspace, weights, interrupts, output.json_out,
            bodies[0], kept,
        )  # fmt: skip
        if not done:
            Console(stderr=True).print("interrupted before the first run finished: nothing written")
            raise typer.Exit(130)
        data = _write(
            problem, done, solver_name, weights, (names, goal.points, front_bodies), workspace,
            output, interrupts, bodies,
        )  # fmt: skip
    result = data.pop("_result")
    if output.json_out:
        typer.echo(json.dumps(data, indent=2))
    else:
        _print(result, data)
    if data["interrupted"]:
        raise typer.Exit(130)
    if "pareto_error" in data:  # asked for a front and got none: an error, files written
        Console(stderr=True).print(f"[red]{data['pareto_error']}")
        raise typer.Exit(1)


def _problem(
    design: DesignProblem, robot_file: RobotFileOptions, objective: str | None,
    needs_bodies: bool = False,
) -> tuple[Any, dict[str, float], Any, tuple[Any, tuple[Any, ...]]]:  # fmt: skip
    """The synthesis problem of the task and template files, the objective's weights,
    the workspace (the task's tunnel envelope, or ``None``) and the bodies' clearance
    model with the poses it leaves out (``clearance_setup``; the problem's task is
    without them). A clearance objective or a kept clearance (``needs_bodies``) builds
    the model even at a clearance of 0."""
    from dataclasses import replace

    from reachwise.io.task_file import load_task
    from reachwise.synthesis.objectives import check_objective, parse_objective
    from reachwise.synthesis.problem import SynthesisProblem, locked_from_spec
    from reachwise.synthesis.synthesize import clearance_setup

    t = load_task(design.task)
    template = robot_file.load(design.robot)
    if design.min_length is not None:
        template = replace(template, design=replace(template.design, min_length=design.min_length))
    weights = (
        check_objective(template.design.objective, design.robot)
        if objective is None
        else parse_objective(objective)
    )
    workspace = t.envelope if design.tunnel else None
    needs_bodies = needs_bodies or "clearance" in weights
    model, t, unservable = clearance_setup(template, t, workspace, design.clearance, needs_bodies)
    problem = SynthesisProblem(template, t, locked_from_spec(template, design.lock or None))
    return problem, weights, workspace, (model, unservable)


def _runs(
    problem: Any, starts: MultiStart, solver: Any, workspace: Any,
    weights: dict[str, float], interrupts: Interrupts, quiet: bool, clearance: Any = None,
    keep: tuple[str, ...] | None = None,
) -> list[Any]:  # fmt: skip
    """The multi-start runs ``seed, seed + 1, ...`` until ``runs`` are done or Ctrl-C:
    asked between the runs, as the compiled code inside one must not be interrupted."""
    from reachwise.synthesis.solver_options import SolverOptions
    from reachwise.synthesis.synthesize import run_once

    runs, seed = starts.runs, starts.seed
    options = SolverOptions(clearance_starts=starts.clearance_starts)

    done = []
    with Progress(
        TextColumn("[bold]synthesis"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
        TextColumn("{task.description}"), console=Console(stderr=True), disable=quiet,
    ) as bar:  # fmt: skip
        job = bar.add_task("", total=runs)
        try:
            for i in range(runs):
                if interrupts.requested:
                    break
                r = run_once(
                    problem, seed + i, solver, options=options, workspace=workspace,
                    objective=weights, clearance=clearance, keep=keep,
                )  # fmt: skip
                done.append(r)
                bar.update(job, advance=1, description=f"run {i}: {r.n_reached}/{problem.K}")
        except KeyboardInterrupt:  # raised by Python code, not by the handler
            interrupts.stop()
    return done


def _write(
    problem: Any, done: list[Any], solver: Any, weights: dict[str, float],
    sweep: tuple[tuple[str, str] | None, int, Any], workspace: Any, output: SynthesisOutput,
    interrupts: Interrupts, bodies: tuple[Any, tuple[Any, ...]] = (None, ()),
) -> dict[str, Any]:  # fmt: skip
    """Write the finished runs (and, if not interrupted, the Pareto sweep of
    ``sweep = (objective names, weightings, the bodies' model the sweep keeps)``) into
    ``output.out``; the summary data (with the result under ``_result``)."""
    from reachwise.report.synthesis import save_synthesis_figures, write_synthesis_report
    from reachwise.results.synthesis_out import summary, write_synthesis
    from reachwise.synthesis.synthesize import result_of

    result = result_of(problem, done, solver, weights, bodies[1], bodies[0])
    folder = write_synthesis(result, output.out)
    pngs = save_synthesis_figures(result, folder) if output.figures else False
    names, points, front_bodies = sweep
    extra = []
    front = None
    if names is not None and not interrupts.requested:
        try:
            front, section = _pareto(
                result,
                names,
                points,
                workspace,
                folder,
                output.figures,
                output.json_out,
                interrupts.check,
                front_bodies,
            )
        except KeyboardInterrupt:
            section = None
        if section is not None:
            extra.append(section)
    report = write_synthesis_report(result, folder, pngs, extra)
    data = summary(result)
    if front is not None and "error" in front:
        data["pareto_error"] = front["error"]
    elif front is not None:
        data["pareto"] = front
    data["interrupted"] = interrupts.requested
    data["out"] = str(folder)
    data["report"] = str(report)
    data["_result"] = result
    return data


def _front_bodies(goal: DesignObjective, names: tuple[str, str] | None, model: Any) -> Any:
    """The bodies' model every design of the sweep keeps: the runs' (``--clearance``),
    or one at ``--front-clearance`` (> 0, at most the runs' clearance, so the start
    design keeps it)."""
    fc = goal.front_clearance
    if fc is None:
        return model
    hint = "--front-clearance"
    if names is None:
        raise typer.BadParameter("needs --pareto", param_hint=hint)
    if model is None or model.clearance <= 0:
        raise typer.BadParameter("needs bodies kept clear (--clearance > 0)", param_hint=hint)
    if not 0 < fc <= model.clearance:
        raise typer.BadParameter(
            f"must be > 0 and at most --clearance {model.clearance:g} m, got {fc:g}",
            param_hint=hint,
        )
    from reachwise.synthesis.clearance import ClearanceModel

    return ClearanceModel(model.robot, model.envelope, fc)


def _pareto_names(text: str) -> tuple[str, str]:
    from reachwise.synthesis.objectives import OBJECTIVES

    names = tuple(n.strip() for n in text.split(",") if n.strip())
    if len(names) != 2 or names[0] == names[1]:
        raise typer.BadParameter("two different objectives, e.g. gci,size", param_hint="--pareto")
    for n in names:
        if n not in OBJECTIVES:
            raise typer.BadParameter(
                f"{n!r}: one of {', '.join(OBJECTIVES)}", param_hint="--pareto"
            )
    return names[0], names[1]


def _keep_names(text: str | None) -> tuple[str, ...] | None:
    """``--keep``'s names (``None`` when not given: the default of ``synthesis.keep``)."""
    from reachwise.errors import InputError
    from reachwise.synthesis.keep import parse_keep

    if text is None:
        return None
    try:
        return parse_keep(text)
    except InputError as e:
        raise typer.BadParameter(str(e), param_hint="--keep") from None


def _pareto(
    result: Any, names: tuple[str, str], points: int, workspace: Any, folder: Path,
    figures: bool, quiet: bool, stop: Callable[[], None] | None = None, bodies: Any = None,
) -> tuple[dict[str, Any] | None, Any]:  # fmt: skip
    """The Pareto sweep from the best run (if it reaches every pose): files in
    ``folder/pareto/``, the report section, and the data for the summary. ``stop`` is
    called between the sweep's solves; it may raise to end the sweep, whose designs
    found until then are written as a partial front. Without ``quiet``, one progress
    line per solve on stderr."""
    from reachwise.report.design import pareto_figure, pareto_section
    from reachwise.report.html import section
    from reachwise.report.png import save_png
    from reachwise.results.pareto_out import write_pareto
    from reachwise.synthesis.pareto import ParetoOptions, pareto_sweep

    best = result.best
    if not best.reached.all():
        reason = no_sweep_reason(result)
        return {"error": reason}, section(
            f"Pareto front: {names[0]} vs {names[1]}", reason, id="pareto"
        )
    prob = result.problem
    if not quiet:
        Console(stderr=True).print(f"Pareto sweep {names[0]}/{names[1]}: {points} weightings")
    front = pareto_sweep(
        prob, prob.pack(best.design, best.q), names, points, workspace,
        ParetoOptions(progress=None if quiet else _sweep_printer(names)), stop=stop,
        clearance=bodies,
    )  # fmt: skip
    data = write_pareto(
        front, folder / "pareto", clearance=bodies.clearance if bodies is not None else 0.0
    )
    fig = pareto_figure(front) if figures else None
    if fig is not None:
        save_png(fig, folder / "pareto" / "front.png", dpi=110)
    return data, pareto_section(front, data, fig)


def _sweep_printer(names: tuple[str, str]) -> Callable[[ParetoProgress], None]:
    """A ``pareto_sweep`` progress callback printing one line per improvement on
    stderr (a line, not a live bar: the sweep runs for minutes, and a log or a pipe
    sees each solve): solves done of the budget, the stage, the front so far and the
    last design's two objective values, with the time since the sweep began."""
    console = Console(stderr=True, highlight=False)
    began = time.monotonic()

    def show(event: ParetoProgress) -> None:
        (a, b), (va, vb) = names, event.values
        took = int(time.monotonic() - began)
        console.print(
            f"pareto {event.solves}/{event.budget} {event.stage}: {event.front} on the "
            f"front; last {a} {va:.4g}, {b} {vb:.4g} ({took // 60}:{took % 60:02d})",
            soft_wrap=True,
        )

    return show


def no_sweep_reason(result: Any, listed: int = 8) -> str:
    """Why ``--pareto`` made no front: the sweep starts from a run's design that
    reaches every pose (and, with bodies, keeps every watched pair the clearance
    apart there), and no run did. Names the best run, how many poses it served and
    the poses it missed, each with what it missed (position, orientation, clearance:
    the smallest term and its pair)."""
    best = result.best
    K = len(best.reached)
    clear = result.clearance
    lost = {"full": [], "position": ["orientation"], "orientation": ["position"]}
    missed = []
    for i in [i for i, ok in enumerate(best.reached) if not ok][:listed]:
        what = list(lost.get(best.status[i], ["position", "orientation"]))
        if best.clearance is not None and best.clearance[i] < clear:
            pair = "–".join(best.clearance_pairs[i]) if best.clearance_pairs else ""
            what.append(f"clearance {best.clearance[i]:.4f} m < {clear:g} m {pair}".rstrip())
        missed.append(f"{result.problem.task.names[i]} ({', '.join(what)})")
    more = K - int(best.reached.sum()) - len(missed)
    held = f", with every watched pair of bodies at least {clear:g} m apart" if clear > 0 else ""
    return (
        f"no Pareto sweep: it starts from a design that reaches every kept pose{held}, and "
        f"none of the {len(result.runs)} runs did. The best (seed {best.seed}) serves "
        f"{int(best.reached.sum())}/{K}; missed: {'; '.join(missed)}"
        + (f"; and {more} more" if more > 0 else "")
        + ". More --runs"
        + (", or a smaller --clearance," if clear > 0 else "")
        + " may give such a design; the runs are written."
    )


def _print(result: object, data: dict) -> None:  # type: ignore[type-arg]
    from reachwise.report.design import SIDE, bound_flag
    from reachwise.results.synthesis_out import design_rows

    console = Console()
    b = data["best"]
    console.print(
        f"{data['template']} on {data['task']}: {data['runs_reaching_all']}/{data['runs']} runs "
        f"reach all {data['task_points']} points; best seed {data['best_seed']}: "
        f"{b['reached']} reached, e_obj {b['e_obj']:.3g}, GCI {b['gci_initial']:.3f} → "
        f"{b['gci']:.3f}, KCI {b['kci_initial']:.3f} → {b['kci']:.3f}"
    )
    if "reach_only" in b:
        ro, ov = b["reach_only"], b["objective_values"]
        console.print(
            "objective " + ", ".join(f"{k}:{v:g}" for k, v in data["objective"].items())
            + ": reach-only → improved design: "
            + ", ".join(f"{n} {ro[n]:.4g} → {ov[n]:.4g}" for n in ("gci", "kci", "size",
                        "limits", "bounds", "clearance") if n in ro and n in ov)
        )  # fmt: skip
        if b.get("kept"):
            console.print("kept (never worse than reach-only): " + ", ".join(b["kept"]))
    if "clearance" in data:
        c = data["clearance"]
        small = c["smallest_m"]
        console.print(
            f"bodies kept {c['required_m']:g} m clear; smallest clearance "
            + (f"{small:.3f} m" if small is not None else "–")
        )
        for u in c["unservable"]:
            console.print(f"[yellow]left out {u['name']}: {u['reason']}")
    free = data["unconstrained"]
    if free:
        console.print(
            f"[yellow]warning: the task's {data['task_points']} poses leave "
            f"{len(free)} of {len(data['design_parameters'])} design parameters unconstrained "
            "(every reaching run kept them at its random start; joint motion alone served "
            f"each pose): {', '.join(free)}. Add poses or dimensions to the task, or an "
            "objective (--objective)"
        )
    hits = data["bound_hits"]
    if hits:
        console.print(
            f"[yellow]bounds hit ({len(hits)}): "
            + ", ".join(f"{h['parameter']} {SIDE[h['side']]}" for h in hits)
        )
    t = Table(title="normalized design parameters (P-I Table 3)")
    for c in ("parameter", "initial", "optimized", "changed %", "bound flag"):
        t.add_column(c, justify="right")
    for row in design_rows(result):  # type: ignore[arg-type]
        t.add_row(*row, bound_flag(hits, row[0]) or "–")
    console.print(t)
    if "pareto" in data:
        f = data["pareto"]
        a, bb = f["objectives"]
        console.print(
            f"Pareto front {a}/{bb}: {f['front_size']} non-dominated of {len(f['points'])} "
            "designs, each reaching every pose (pareto/: front.csv, point-K/design.yaml|urdf)"
        )
        if f["partial"]:
            console.print("[yellow]partial front: the sweep was interrupted; its designs so far")
        for r in f["points"]:
            if r["front"]:
                console.print(f"  #{r['index']}: {a} {r['values'][a]:.4g}, {bb} "
                              f"{r['values'][bb]:.4g}  {r['design_yaml']}")  # fmt: skip
    console.print(f"wrote {data['out']}/ (design.yaml, design.urdf, summary.json, points.csv)")
    console.print(f"report: {data['report']}")
