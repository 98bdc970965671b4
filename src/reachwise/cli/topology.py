"""``reachwise topology``: the two-round topology sweep of P-II Fig. 1, resumable."""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from reachwise.cli._help import builtins
from reachwise.cli._options import cli, typed_command


def _bounds(text: str, option: str) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in text.split(":"))
    except ValueError:
        raise typer.BadParameter(
            f"{text!r}: expected LO:HI, e.g. -2:2", param_hint=option
        ) from None
    if not lo <= hi:
        raise typer.BadParameter(f"{text!r}: LO > HI", param_hint=option)
    return lo, hi


@dataclass(frozen=True)
class SweepSettings:
    """The sweep: the ``task`` (a file or built-in name), round 1 on ``subset``
    descriptive points (``None``: none), the ``top`` topologies to round 2, ``runs``
    multi-start runs per topology from ``seed``, the ranking key, the objective every
    reaching run is improved for (``None``: none), the ``clearance`` of stand-in link
    bodies of ``body_radius`` (0: none), runs per submitted ``batch`` and the task's
    tunnel envelope kept (``tunnel``)."""

    #: Task file or built-in task name.
    task: str = cli(
        typer.Option(..., "--task", help=f"Task file or built-in task ({builtins('tasks')}).")
    )
    #: Round-1 descriptive task points; ``None``: the whole task.
    subset: int | None = cli(
        typer.Option(
            None, "--subset", min=1, help="Round 1 on N descriptive task points (default: none)."
        )
    )
    #: Feasible topologies taken to round 2.
    top: int = cli(typer.Option(3, "--top", min=1, help="Feasible topologies taken to round 2."))
    #: Multi-start runs per topology.
    runs: int = cli(typer.Option(3, "--runs", min=1, help="Multi-start runs per topology."))
    #: Seed of run 0; run i uses seed + i.
    seed: int = cli(typer.Option(0, "--seed", help="Seed of run 0; run i uses seed+i."))
    #: Ranking key (reachwise.synthesis.rank).
    rank_key: str = cli(
        typer.Option(
            "mean",
            "--rank",
            help="mean, gci, kci, manipulability, length, prismatic, or an objective: size, "
            "limits, bounds, clearance.",
        )
    )
    #: Clearance of the stand-in link bodies (m); 0: off.
    clearance: float = cli(
        typer.Option(
            0.0,
            "--clearance",
            min=0.0,
            help="Keep stand-in link bodies (capsules of --body-radius along every link) "
            "this far apart and from the tunnel at every pose (m; 0: off); a topology whose "
            "best run is less clear at a pose does not reach it.",
        )
    )
    #: Radius of the stand-in link bodies (m), with a clearance.
    body_radius: float = cli(
        typer.Option(0.1, "--body-radius", min=0.0, help="Radius of the stand-in link bodies (m).")
    )
    #: Weighted objectives, e.g. gci:1,size:0.2; ``None``: reach only.
    objective: str | None = cli(
        typer.Option(
            None,
            "--objective",
            help="Improve every reaching run for weighted objectives, e.g. gci:1,size:0.2.",
        )
    )
    #: Runs per submitted batch.
    batch: int = cli(typer.Option(1, "--batch", min=1, help="Runs per submitted batch."))
    #: Keep links inside the task's tunnel envelope.
    tunnel: bool = cli(
        typer.Option(
            True, "--tunnel/--no-tunnel", help="Keep links inside the task's tunnel envelope."
        )
    )


@dataclass(frozen=True)
class TemplateBounds:
    """Bounds of the templates' free parameters, each ``LO:HI``: every free a, d
    (``lengths``, m), the prismatic stroke (``stroke``, m) and the base x, y, z
    (``base_box``, m)."""

    #: Bounds of every free a, d (m), LO:HI.
    lengths: str = cli(typer.Option("-2:2", "--lengths", help="Bounds of every free a, d (m)."))
    #: Prismatic joint stroke (m), LO:HI.
    stroke: str = cli(typer.Option("0:3", "--stroke", help="Prismatic joint stroke (m)."))
    #: Bounds of base x, y, z (m), LO:HI.
    base_box: str = cli(typer.Option("-2:2", "--base-box", help="Bounds of base x, y, z (m)."))

    def options(self) -> Any:
        """The :class:`~reachwise.synthesis.topology.TemplateOptions` of the bounds."""
        from reachwise.synthesis.topology import TemplateOptions

        lo, hi = _bounds(self.base_box, "--base-box")
        return TemplateOptions(
            length_bounds=_bounds(self.lengths, "--lengths"),
            prismatic_limits=_bounds(self.stroke, "--stroke"),
            base_bounds={c: (lo, hi) for c in "xyz"},
        )


@dataclass(frozen=True)
class TopologySource:
    """Which topologies to sweep: exactly one of a built-in set (``--set``),
    enumeration rules (``--enumerate``) or specs (``--spec``)."""

    #: Built-in topology set (p2).
    set_name: str | None = cli(
        typer.Option(None, "--set", help="Built-in topology set: p2 (the six P-II configurations).")
    )
    #: Enumeration rules (reachwise.synthesis.topology.parse_rules).
    rules: str | None = cli(
        typer.Option(
            None,
            "--enumerate",
            help="Enumerate topologies under rules, e.g. 'joints=6 prismatic=0-2 first=vertical "
            "sample=40' (see reachwise.synthesis.topology.parse_rules).",
        )
    )
    #: Topology specs, e.g. RRPRRR.
    specs: list[str] = cli(
        typer.Option(
            [], "--spec", help="A topology spec, e.g. 'RRPRRR' or 'R(0) R(90) P(90) …' (repeat)."
        )
    )

    def check(self) -> None:
        given = (self.set_name, self.rules, self.specs or None)
        if sum(x is not None for x in given) != 1:
            raise typer.BadParameter("give exactly one of --set, --enumerate, --spec")

    def topologies(self, task: Any, options: Any) -> list[Any]:
        """The topologies for ``task`` (enumeration needs as many rotation axes as the
        task's dimension asks for, unless the rules say otherwise)."""
        from reachwise.io.robot_file import load_robot
        from reachwise.synthesis.topology import (
            builtin_set,
            enumerate_topologies,
            parse_rules,
            topologies_from_specs,
        )

        if self.set_name is not None:
            topos = builtin_set(self.set_name, load_robot)
        elif self.rules is not None:
            r = parse_rules(self.rules)
            if "rotations=" not in self.rules:  # rule 4 from the task: 6-D needs 3 axes, 5-D 2
                need = {6: 3, 5: 2, 3: 0}[int(task.dims.max())]
                r = replace(r, min_rotation_axes=need)
            topos = topologies_from_specs(enumerate_topologies(r, options), options)
        else:
            topos = topologies_from_specs(list(self.specs), options)
        if not topos:
            raise typer.BadParameter("the rules leave no topology")
        return list(topos)


@dataclass(frozen=True)
class SweepPlace:
    """Where the runs execute: ``workers`` processes (``None`` all cores, 0 in
    process), or a dask scheduler (``tcp://HOST:8786`` or ``local``)."""

    #: Worker processes; ``None``: all cores, 0: in process.
    workers: int | None = cli(
        typer.Option(
            None, "--workers", min=0, help="Worker processes (default all cores; 0 = in process)."
        )
    )
    #: Dask scheduler tcp://HOST:8786 or 'local'; ``None``: no dask.
    dask: str | None = cli(
        typer.Option(
            None, "--dask", help="Dask scheduler tcp://HOST:8786, or 'local' (LocalCluster)."
        )
    )

    def check(self) -> None:
        if self.dask is not None and self.workers == 0:
            raise typer.BadParameter("--workers 0 runs in process; drop it with --dask")


@dataclass(frozen=True)
class SweepOutput:
    """Where the sweep goes: the results database ``db``, the report folder ``out``,
    whether to draw PNG ``figures``, only list the topologies (``list_only``), and JSON
    (``json_out``) or a table on stdout."""

    #: SQLite results database (created or resumed).
    db: Path = cli(
        typer.Option(
            ...,
            "--db",
            help="SQLite results database (created or resumed; stored runs of other code or "
            "libraries are run again).",
        )
    )
    #: Report folder.
    out: Path = cli(typer.Option(..., "--out", help="Report folder."))
    #: Write PNG figures.
    figures: bool = cli(typer.Option(True, "--figures/--no-figures", help="Write PNG figures."))
    #: Only list the topologies.
    list_only: bool = cli(typer.Option(False, "--list", help="Only list the topologies."))
    #: Print the report as JSON.
    json_out: bool = cli(typer.Option(False, "--json", help="Print the report as JSON."))


@typed_command(
    order=(
        "task",
        "set_name",
        "rules",
        "specs",
        "db",
        "out",
        "subset",
        "top",
        "runs",
        "seed",
        "rank_key",
        "objective",
        "clearance",
        "body_radius",
        "workers",
        "dask",
        "batch",
        "lengths",
        "stroke",
        "base_box",
        "tunnel",
        "figures",
        "list_only",
        "json_out",
    )
)
def topology(
    sweep: SweepSettings, source: TopologySource, bounds: TemplateBounds, place: SweepPlace,
    output: SweepOutput,
) -> None:  # fmt: skip
    """Optimize many topologies and rank them by GCI, KCI and more (P-II Fig. 1, Table 2).

    Every finished run is stored in --db at once; running the same command again skips
    what is done. A stored run computed by other code (another checkout or version of
    reachwise, another numpy, scipy or Python) is run again and replaced, and the progress
    output says how many: the table is always the one this code computes. Ctrl-C (once or
    more) stops submitting, waits for the running runs, stores them and exits (130); a
    killed sweep loses nothing it stored.
    """
    from dataclasses import replace

    from reachwise.io.task_file import load_task
    from reachwise.synthesis.objectives import parse_objective
    from reachwise.synthesis.rank import check_key
    from reachwise.synthesis.sweep import SweepConfig

    source.check()
    key = check_key(sweep.rank_key)
    place.check()
    t = load_task(sweep.task)
    options = bounds.options()
    if sweep.clearance > 0:
        options = replace(options, body_radius=sweep.body_radius)
    topos = source.topologies(t, options)
    if output.list_only:
        _list(topos, output.json_out)
        return
    cfg = SweepConfig(
        subset=sweep.subset, top=sweep.top, runs=sweep.runs, seed=sweep.seed, rank_key=key,
        workspace=sweep.tunnel, batch_size=sweep.batch,
        objective=parse_objective(sweep.objective) if sweep.objective else None,
        clearance=sweep.clearance,
    )  # fmt: skip
    result = _sweep(t, topos, cfg, place, output)
    _report(result, output)


def _sweep(t: Any, topos: list[Any], cfg: Any, place: SweepPlace, output: SweepOutput) -> Any:
    """Run the sweep with a progress bar, storing every run in ``output.db``; on
    Ctrl-C say what is stored and how to resume, and exit with 130. SIGINT is only
    recorded while the sweep runs (compiled code in process must not be interrupted)
    and honoured after each stored run."""
    from reachwise.cli.interrupts import deferred_interrupts
    from reachwise.results.sweep_store import SweepStore
    from reachwise.synthesis.sweep import SweepInterrupted, dask_executor, run_sweep

    console = Console(stderr=True)
    interrupted, stored = False, 0
    with deferred_interrupts() as interrupts, SweepStore(output.db) as store, Progress(
        TextColumn("[bold]{task.fields[label]}"), BarColumn(), MofNCompleteColumn(),
        TimeElapsedColumn(), TextColumn("{task.description}"), console=console,
        disable=output.json_out,
    ) as bar:  # fmt: skip
        jobs: dict[int, Any] = {}

        def on_event(e: Any) -> None:
            interrupts.check()
            if e.kind == "round":
                label = "round 1 (subset)" if e.round == 1 else "round 2 (complete task)"
                jobs[e.round] = bar.add_task("", total=e.total, completed=e.done, label=label)
                if e.stale:
                    console.print(
                        f"{label}: {e.stale} runs stored in {output.db} were computed by other "
                        "code or libraries; running them again"
                    )
            elif e.kind == "topology":
                bar.update(jobs[e.round], completed=e.done, description=e.topology[:40])
            elif e.kind == "item" and e.result is not None:
                r = e.result
                bar.update(
                    jobs[e.round],
                    description=f"{r.topology[:40]} run {r.run}: {r.n_reached}/{r.n_points}",
                )

        try:
            if place.dask is not None:
                with dask_executor(place.dask, place.workers) as ex:
                    result = run_sweep(t, topos, cfg, executor=ex, store=store, on_event=on_event)
            else:
                result = run_sweep(
                    t, topos, cfg, workers=place.workers, store=store, on_event=on_event
                )
        except SweepInterrupted:
            interrupted = True
            stored = store.count()
    if interrupted:
        console.print(
            f"interrupted: {stored} finished runs are stored in {output.db}; run the same "
            "command to resume"
        )
        raise typer.Exit(130)
    return result


def _report(result: Any, output: SweepOutput) -> None:
    """Write the ranking and the topology report into ``output.out`` and print them."""
    from reachwise.report.ranking import write_report
    from reachwise.report.topology import write_topology_report

    data = write_report(result, output.out, figures=output.figures)
    data["db"] = str(output.db)
    data["out"] = str(output.out)
    data["report"] = str(write_topology_report(result, output.out, data["designs"], output.figures))
    if output.json_out:
        typer.echo(json.dumps(data, indent=2))
    else:
        _print(result, data)


def _list(topos: list[Any], json_out: bool) -> None:
    if json_out:
        typer.echo(json.dumps([{"name": t.name, "types": t.spec.types} for t in topos], indent=2))
        return
    console = Console()
    for t in topos:
        console.print(f"{t.spec.types:10s} {t.name}")
    console.print(f"{len(topos)} topologies")


def _print(result: Any, data: dict[str, Any]) -> None:
    console = Console()
    tab = Table(
        title=f"topology sweep on {data['task']}: final ranking by {result.config.rank_key} "
        "(P-II Table 2)"
    )
    for c in ("rank", "topology", "round", "GCI", "KCI", "mean", "reached", "note"):
        tab.add_column(c, justify="right" if c not in ("topology",) else "left")
    for r in data["table"]:
        ok = r["feasible"]

        def f(k: str, r: dict[str, Any] = r, ok: bool = ok) -> str:
            return f"{r[k]:.4f}" if ok and r[k] is not None else "–"

        tab.add_row(
            "–" if r["rank"] is None else str(r["rank"]),
            r["topology"],
            str(r["round"]),
            f("gci"),
            f("kci"),
            f("mean"),
            f"{r['reached']}/{r['points']}",
            r["note"],
        )
    console.print(tab)
    console.print(
        f"{data['new_items']} runs done now ({data['stale_items']} of them replacing runs "
        f"of other code), {data['stored_items']} found in {data['db']}; "
        f"wrote {data['out']}/ (ranking.md, ranking.csv, ranking.json, designs/)"
    )
    console.print(f"report: {data['report']}")


def main() -> None:
    """Run ``topology`` as a stand-alone command (``python -m reachwise.cli.topology``)."""
    from reachwise.errors import ReachwiseError

    try:
        typer.run(topology)
    except ReachwiseError as exc:
        typer.secho(f"error: {exc}", err=True, fg=typer.colors.RED)
        raise SystemExit(2) from None


if __name__ == "__main__":
    main()
