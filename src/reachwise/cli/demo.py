"""``reachwise demo``: the main job on embedded defaults, resumable stage by stage.

Stages (each writes its outputs and an HTML report into its own folder of ``--out``):

1. ``task`` — generate the ``tunnel-87`` drilling task (10 plans → 87 points, P-I §4)
   and check it equals the built-in file (``tunnel-87.yaml``);
2. ``kinematics`` — IK and conditioning of the built-in robots (``kinematics.json``);
3. ``synthesis`` — the dimensional synthesis of the ``sb60`` boom for it
   (``synthesis-sb60-tunnel-87/``, P-I Tables 3–4);
4. ``topology`` — the six P-II topologies ranked: round 1 on a descriptive subset of
   the task, the best on the complete task (``topology-p2-tunnel-87/``, P-II Table 2);
5. ``p3`` / ``p5`` — the P-III self-collision and P-V crane-and-scanned-obstacle
   experiments, with and without avoidance (``simulate-p3-self-collision/``,
   ``simulate-p5-crane-obstacle/``);
6. ``distance`` — exact point-cloud distances against brute force (``distance.json``).

``report.html`` at the top summarises every stage and links its report. A finished
stage leaves ``stage.json`` (or its JSON file) holding its parameters and key figures;
a rerun with the same parameters reuses it (``--fresh`` redoes everything). Ctrl-C
keeps every finished stage (and every finished topology run, in the sweep database):
SIGINT is recorded and honoured between a stage's steps, never inside compiled code.
"""

from __future__ import annotations

import json
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import typer
from rich.console import Console
from rich.table import Table

import reachwise.cli.demo_stages as stages
from reachwise.cli._options import cli, typed_command
from reachwise.cli.demo_stages import Ctx, StageOutput
from reachwise.io.atomic import atomic_write

SCENARIOS = ("p3-self-collision", "p5-crane-obstacle")
TOPOLOGY_FOLDER = "topology-p2-tunnel-87"
SYNTHESIS_FOLDER = "synthesis-sb60-tunnel-87"


@dataclass(frozen=True)
class Stage:
    """One step of the demo: ``run(ctx, folder, params)`` writes into ``folder``."""

    key: str
    title: str
    folder: str | None
    params: dict[str, Any]
    run: Callable[[Ctx, Path, dict[str, Any]], StageOutput]

    def marker(self, out: Path) -> Path:
        return out / self.folder / "stage.json" if self.folder else out / f"{self.key}.json"


@dataclass(frozen=True)
class DemoSettings:
    """How much the demo does: synthesis ``runs``, ``topology_runs`` per topology and
    round, the round-1 ``subset`` of descriptive points, the ``top`` topologies to the
    complete task, sweep ``workers`` (``None``: all cores, 0: in process), the
    ``seed`` of every random draw and the tiny ``quick`` demo of the tests."""

    #: Synthesis runs (multi-start).
    runs: int = cli(
        typer.Option(10, "--runs", min=1, help="Synthesis runs (multi-start; P-I Table 4 used 10).")
    )
    #: Runs per topology and sweep round.
    topology_runs: int = cli(
        typer.Option(2, "--topology-runs", min=1, help="Runs per topology and sweep round.")
    )
    #: Descriptive task points of topology round 1.
    subset: int = cli(
        typer.Option(20, "--subset", min=2, help="Descriptive task points of the topology round 1.")
    )
    #: Topologies taken to the complete task.
    top: int = cli(typer.Option(3, "--top", min=1, help="Topologies taken to the complete task."))
    #: Sweep worker processes; ``None``: all cores, 0: in process.
    workers: int | None = cli(
        typer.Option(
            None, "--workers", min=0, help="Sweep worker processes (default all cores; 0 = none)."
        )
    )
    #: Seed of every random draw.
    seed: int = cli(typer.Option(0, help="Seed of every random draw."))
    #: Tiny demo for tests.
    quick: bool = cli(
        typer.Option(
            False, "--quick", hidden=True, help="Tiny demo for tests: 8 task points, short runs."
        )
    )


@dataclass(frozen=True)
class DemoOutput:
    """Where the demo goes: the ``out`` folder, whether to redo the stages complete
    there (``fresh``), open the viewer on the results (``view``) and print JSON
    (``json_out``)."""

    #: Folder for the results.
    out: Path = cli(typer.Option(Path("reachwise-demo"), "--out", help="Folder for the results."))
    #: Redo stages already complete on disk.
    fresh: bool = cli(typer.Option(False, "--fresh", help="Redo stages already complete on disk."))
    #: Open the viewer on the results.
    view: bool = cli(typer.Option(False, "--view", help="Open the viewer on the results."))
    #: Print the key figures as JSON.
    json_out: bool = cli(typer.Option(False, "--json", help="Print the key figures as JSON."))


@typed_command(
    order=(
        "out",
        "runs",
        "topology_runs",
        "subset",
        "top",
        "workers",
        "seed",
        "fresh",
        "view",
        "json_out",
        "quick",
    )
)
def demo(settings: DemoSettings, output: DemoOutput) -> None:
    """Run the main job on built-in defaults: task, synthesis, topology ranking, the
    P-III and P-V avoidance experiments; write reports, print the key figures.

    A rerun reuses the stages already complete in --out; Ctrl-C keeps them.
    """
    from reachwise.cli.interrupts import deferred_interrupts
    from reachwise.report.demo import write_demo_report

    out, json_out, seed = output.out, output.json_out, settings.seed
    console = Console(quiet=json_out)
    ctx = Ctx(
        out, seed, settings.quick, settings.runs, settings.topology_runs, settings.subset,
        settings.top, settings.workers, console, Console(stderr=True, quiet=json_out), json_out,
    )  # fmt: skip
    out.mkdir(parents=True, exist_ok=True)
    stages = _stages(ctx)
    if output.fresh:
        _clear(out, stages)
    t0 = time.perf_counter()
    with deferred_interrupts() as interrupts:
        ctx.check = interrupts.check
        interrupted = _run_stages(ctx, stages)
    elapsed = time.perf_counter() - t0
    figures: dict[str, Any] = {
        "seed": seed,
        "out": str(out.resolve()),
        "elapsed_s": elapsed,
        "stages_s": sum(v["elapsed_s"] for v in ctx.done.values()),
        "interrupted": interrupted,
        "stages": {k: v["status"] for k, v in ctx.done.items()},
        **{k: v["result"] for k, v in ctx.done.items()},
    }
    report = write_demo_report(out, [(s, ctx.done.get(s.key)) for s in stages], figures)
    figures["report"] = str(report.resolve())
    atomic_write(out / "demo.json", json.dumps(figures, indent=2, default=str))
    if interrupted is not None:  # on stderr even with --json: what was kept, how to resume
        Console(stderr=True).print(
            f"[bold red]interrupted[/] during {interrupted}: {len(ctx.done)} finished stages "
            f"kept in {out.resolve()}/; run the same command to resume"
        )
        if json_out:
            typer.echo(json.dumps(figures, indent=2, default=str))
        raise typer.Exit(130)
    _print_summary(ctx, stages, elapsed, report)
    if json_out:
        typer.echo(json.dumps(figures, indent=2, default=str))
    if output.view:
        from reachwise.viz.viewer import serve_results

        serve_results(out, block=True)


def _run_stages(ctx: Ctx, stages: list[Stage]) -> str | None:
    """Run (or reuse) each stage in turn until Ctrl-C: the key of the stage it stopped,
    or ``None``. SIGINT is only recorded (the compiled kernels must not be interrupted)
    and honoured between a stage's steps (``ctx.check``) and between stages."""
    for st in stages:
        try:
            ctx.check()
            ctx.done[st.key] = _run_stage(ctx, st)
        except KeyboardInterrupt:
            return st.key
    return None


def _stages(ctx: Ctx) -> list[Stage]:
    q = ctx.quick
    base = {"seed": ctx.seed, "quick": q}
    sim = {**base, "duration": 3.0 if q else None}
    return [
        Stage("task", "generate the tunnel-87 task (P-I §4)", None, base, stages.task),
        Stage(
            "kinematics",
            "IK and conditioning of the built-in robots",
            None,
            {**base, "targets": 5 if q else 50},
            stages.kinematics,
        ),
        Stage(
            "synthesis",
            "synthesis of the sb60 boom for tunnel-87 (P-I)",
            SYNTHESIS_FOLDER,
            {**base, "runs": 2 if q else ctx.runs, "objective": {"gci": 1.0}},
            stages.synthesis,
        ),
        Stage(
            "topology",
            "ranking the P-II topologies (P-II Table 2)",
            TOPOLOGY_FOLDER,
            {
                **base,
                "runs": 1 if q else ctx.topology_runs,
                "subset": 4 if q else ctx.subset,
                "top": 1 if q else ctx.top,
            },
            stages.topology,
        ),
        *(
            Stage(
                s[:2],
                f"{s}: with and without avoidance",
                f"simulate-{s}",
                {**sim, "scenario": s},
                stages.simulate,
            )
            for s in SCENARIOS
        ),
        Stage(
            "distance",
            "exact point-cloud distances (P-V scan, §3.1)",
            None,
            {**base, "queries": 20 if q else 200},
            stages.distance,
        ),
    ]


def _clear(out: Path, stages: list[Stage]) -> None:
    """``--fresh``: remove what the stages wrote (only the demo's own names)."""
    for st in stages:
        if st.folder:
            shutil.rmtree(out / st.folder, ignore_errors=True)
        st.marker(out).unlink(missing_ok=True)
    for name in ("tunnel-87.yaml", "report.html", "demo.json"):
        (out / name).unlink(missing_ok=True)


def _reusable(ctx: Ctx, st: Stage) -> dict[str, Any] | None:
    path = st.marker(ctx.out)
    try:
        rec = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if rec.get("params") != st.params:
        return None
    if not all((ctx.out / f).exists() for f in rec.get("files", [])):
        return None
    return dict(rec)


def _run_stage(ctx: Ctx, st: Stage) -> dict[str, Any]:
    ctx.console.rule(f"{st.title}")
    rec = _reusable(ctx, st)
    if rec is not None:
        rec["status"] = "reused"
        ctx.console.print(f"complete on disk, reused ({st.marker(ctx.out)}; --fresh redoes it)")
        for line in rec.get("lines", []):
            ctx.console.print(line)
        return rec
    folder = ctx.out / st.folder if st.folder else ctx.out
    st.marker(ctx.out).unlink(missing_ok=True)
    t = time.perf_counter()
    output = st.run(ctx, folder, st.params)
    rec = {
        "stage": st.key,
        "params": st.params,
        "elapsed_s": time.perf_counter() - t,
        "files": list(output.files),
        "lines": list(output.lines),
        "report": output.report,
        "result": output.figures,
    }
    for line in rec["lines"]:
        ctx.console.print(line)
    # written last: the stage is complete
    atomic_write(st.marker(ctx.out), json.dumps(rec, indent=2, default=str))
    rec["status"] = "done"
    return rec


# ---- summary -----------------------------------------------------------------------------
def _print_summary(ctx: Ctx, stages: list[Stage], elapsed: float, report: Path) -> None:
    from reachwise.report.demo import key_figures

    c = ctx.console
    c.rule("summary")
    tab = Table(show_header=True)
    for col in ("stage", "key figures", "time", "status"):
        tab.add_column(col, justify="left")
    for st in stages:
        rec = ctx.done.get(st.key)
        if rec is None:
            continue
        tab.add_row(
            st.key,
            "\n".join(key_figures(st.key, rec["result"])),
            f"{rec['elapsed_s']:.0f} s",
            rec["status"],
        )
    c.print(tab)
    c.print(f"done in {elapsed:.1f} s; results in {ctx.out.resolve()}/")
    c.print(f"[bold]report: {report.resolve()}[/]")
