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
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from reachwise.cli._options import cli, typed_command
from reachwise.io.atomic import atomic_write

SCENARIOS = ("p3-self-collision", "p5-crane-obstacle")
TOPOLOGY_FOLDER = "topology-p2-tunnel-87"
SYNTHESIS_FOLDER = "synthesis-sb60-tunnel-87"


@dataclass
class Ctx:
    """What every stage sees: options, the output folder and the consoles."""

    out: Path
    seed: int
    quick: bool
    runs: int
    topology_runs: int
    subset: int
    top: int
    workers: int | None
    console: Console
    err: Console
    json_out: bool
    done: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: Called between the steps of a stage (runs, ticks, queries); raises
    #: :class:`KeyboardInterrupt` once Ctrl-C was pressed
    #: (:meth:`reachwise.cli.interrupts.Interrupts.check`).
    check: Callable[[], None] = lambda: None

    @contextmanager
    def progress(self, label: str) -> Iterator[Progress]:
        with Progress(
            TextColumn(f"[bold]{label}"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            TextColumn("{task.description}"),
            console=self.err,
            disable=self.json_out,
            transient=False,
        ) as bar:
            yield bar

    def task(self) -> Any:
        """The generated task (stage 1's file); in quick mode every 11th point."""
        from reachwise.io.task_file import load_task

        task = load_task(self.out / "tunnel-87.yaml")
        if self.quick:
            task = task.subset(np.arange(0, len(task), 11), name="tunnel-87-quick")
        return task


@dataclass(frozen=True)
class StageOutput:
    """What a stage returns: its key ``figures`` (JSON-able; ``demo.json`` and the
    report show them), the ``files`` it wrote (relative to the demo folder; a rerun
    reuses the stage while they exist), the ``lines`` it prints, and its HTML
    ``report`` (relative path), if it has one."""

    figures: dict[str, Any]
    files: tuple[str, ...] = ()
    lines: tuple[str, ...] = ()
    report: str | None = None


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
        Stage("task", "generate the tunnel-87 task (P-I §4)", None, base, _task),
        Stage(
            "kinematics",
            "IK and conditioning of the built-in robots",
            None,
            {**base, "targets": 5 if q else 50},
            _kinematics,
        ),
        Stage(
            "synthesis",
            "synthesis of the sb60 boom for tunnel-87 (P-I)",
            SYNTHESIS_FOLDER,
            {**base, "runs": 2 if q else ctx.runs, "objective": {"gci": 1.0}},
            _synthesis,
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
            _topology,
        ),
        *(
            Stage(
                s[:2],
                f"{s}: with and without avoidance",
                f"simulate-{s}",
                {**sim, "scenario": s},
                _simulate,
            )
            for s in SCENARIOS
        ),
        Stage(
            "distance",
            "exact point-cloud distances (P-V scan, §3.1)",
            None,
            {**base, "queries": 20 if q else 200},
            _distance,
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


def _rel(ctx: Ctx, p: Path) -> str:
    return str(p.relative_to(ctx.out))


# ---- stages ------------------------------------------------------------------------------
def _task(ctx: Ctx, folder: Path, p: dict[str, Any]) -> StageOutput:
    from reachwise.cli.task import task_summary
    from reachwise.io.task_file import load_task, save_task
    from reachwise.tasks.drilling import tunnel_87

    task = tunnel_87()
    path = ctx.out / "tunnel-87.yaml"
    save_task(task, path)
    builtin = load_task("tunnel-87")
    diff = float(np.abs(load_task(path).positions - builtin.positions).max())
    data = task_summary(task)
    groups = ", ".join(f"{g} {v['points']}" for g, v in data["groups"].items())
    figures = {
        "points": data["points"],
        "groups": {g: v["points"] for g, v in data["groups"].items()},
        "matches_builtin_m": diff,
    }
    line = (
        f"{data['points']} points ({groups}); equals the built-in tunnel-87 within "
        f"{diff:.1e} m; wrote {path}"
    )
    return StageOutput(figures, files=(_rel(ctx, path),), lines=(line,))


def _synthesis(ctx: Ctx, folder: Path, p: dict[str, Any]) -> StageOutput:
    from reachwise.io.robot_file import load_robot
    from reachwise.io.task_file import save_task
    from reachwise.report.synthesis import save_synthesis_figures, write_synthesis_report
    from reachwise.results.synthesis_out import summary, write_synthesis
    from reachwise.synthesis.synthesize import synthesize

    task = ctx.task()
    runs = p["runs"]
    with ctx.progress("synthesis") as bar:
        job = bar.add_task("", total=runs)

        def on_run(r: Any) -> None:
            ctx.check()
            bar.update(job, advance=1, description=f"seed {r.seed}: {r.n_reached}/{len(task)}")

        # reach first, then the conditioning objective (GCI, P-II Eq. 38) in the null
        # space of the task, every pose kept reached
        result = synthesize(
            task, load_robot("sb60"), runs=runs, seed=ctx.seed, on_run=on_run,
            objective=p["objective"],
        )  # fmt: skip
    write_synthesis(result, folder)
    pngs = save_synthesis_figures(result, folder)
    save_task(task, folder / "task.yaml")
    report = write_synthesis_report(result, folder, pngs)
    d = summary(result)
    b = d["best"]
    figures = {
        "task_points": d["task_points"],
        "unknowns": d["unknowns"],
        "runs": d["runs"],
        "runs_reaching_all": d["runs_reaching_all"],
        "best_seed": d["best_seed"],
        "reached": b["reached"],
        "gci": b["gci"],
        "kci": b["kci"],
        "gci_initial": b["gci_initial"],
        "kci_initial": b["kci_initial"],
        "table3": d["table3"],
        "table4": d["table4"],
        "objective": d["objective"],
        "gci_reach_only": b.get("reach_only", {}).get("gci"),
        "kci_reach_only": b.get("reach_only", {}).get("kci"),
        "bound_hits": d["bound_hits"],
    }
    lines = (
        f"{d['task_points']} points, {d['unknowns']} unknowns: {d['runs_reaching_all']}/"
        f"{d['runs']} runs reach every point inside the tunnel",
        _best_line(d),
        *_objective_lines(d),
        f"report: {report}",
    )
    return StageOutput(
        figures,
        files=(_rel(ctx, report), _rel(ctx, folder / "design.yaml")),
        lines=lines,
        report=_rel(ctx, report),
    )


def _best_line(d: dict[str, Any]) -> str:
    """The best run from its random start design to its final design, for the console."""
    b = d["best"]
    return (
        f"best run (seed {d['best_seed']}): {b['reached']}/{d['task_points']} reached; "
        f"from its random start design to the final design: GCI {b['gci_initial']:.4f} → "
        f"{b['gci']:.4f}, KCI {b['kci_initial']:.4f} → {b['kci']:.4f}"
    )


def _objective_lines(d: dict[str, Any]) -> list[str]:
    """The conditioning objective's effect and the bound flags, for the console."""
    b = d["best"]
    out = []
    if "reach_only" in b:
        r, v = b["reach_only"], b["objective_values"]
        out.append(
            f"objective gci: from the first design that reaches every point to the "
            f"improved final design: GCI {r['gci']:.4f} → {v['gci']:.4f}, "
            f"KCI {r['kci']:.4f} → {v['kci']:.4f}, every point still reached"
        )
    hits = d["bound_hits"]
    if hits:
        out.append("bounds hit: " + ", ".join(f"{h['parameter']} ({h['side']})" for h in hits))
    return out


def _topology(ctx: Ctx, folder: Path, p: dict[str, Any]) -> StageOutput:
    from reachwise.io.robot_file import load_robot
    from reachwise.report.ranking import write_report
    from reachwise.report.topology import write_topology_report
    from reachwise.results.sweep_store import SweepStore
    from reachwise.synthesis.sweep import SweepConfig, run_sweep
    from reachwise.synthesis.topology import builtin_set

    task = ctx.task()
    topos = builtin_set("p2", load_robot)
    if ctx.quick:
        topos = [t for t in topos if t.name in ("p2-man1", "p2-man3")]
    cfg = SweepConfig(subset=p["subset"], top=p["top"], runs=p["runs"], seed=ctx.seed)
    workers = 0 if ctx.quick and ctx.workers is None else ctx.workers
    with SweepStore(folder / "sweep.db") as store, ctx.progress("topology") as bar:
        jobs: dict[int, Any] = {}

        def on_event(e: Any) -> None:
            ctx.check()
            if e.kind == "round":
                n = e.total * cfg.runs
                jobs[e.round] = bar.add_task(
                    f"round {e.round}", total=n, completed=e.done * cfg.runs
                )
            elif e.kind == "item" and e.result is not None:
                r = e.result
                bar.update(
                    jobs[e.round],
                    advance=1,
                    description=f"round {e.round}: "
                    f"{r.topology} run {r.run}: {r.n_reached}/{r.n_points}",
                )

        result = run_sweep(task, topos, cfg, workers=workers, store=store, on_event=on_event)
    data = write_report(result, folder)
    report = write_topology_report(result, folder, data["designs"])
    table = [
        {
            k: r[k]
            for k in (
                "rank",
                "topology",
                "round",
                "feasible",
                "reached",
                "points",
                "gci",
                "kci",
                "mean",
                "note",
            )
        }
        for r in data["table"]
    ]
    ranked = result.ranked()
    lines = [
        f"{len(topos)} topologies; round 1 on {cfg.subset} descriptive points, the top "
        f"{cfg.top} on all {len(task)}; {cfg.runs} runs each ({data['new_items']} run now)"
    ]
    for r in table:
        if r["rank"] is not None:
            lines.append(
                f"  #{r['rank']} {r['topology']}: GCI {r['gci']:.4f}, KCI "
                f"{r['kci']:.4f}, mean {r['mean']:.4f}"
            )
    lines.append(f"report: {report}")
    figures = {
        "topologies": [t.name for t in topos],
        "ranked": ranked,
        "table": table,
        "subset": cfg.subset,
        "top": cfg.top,
        "runs": cfg.runs,
    }
    rel = _rel(ctx, report)
    return StageOutput(figures, files=(rel,), lines=tuple(lines), report=rel)


def _simulate(ctx: Ctx, folder: Path, p: dict[str, Any]) -> StageOutput:
    from reachwise.report.sim_plots import save_figures
    from reachwise.report.simulate import leg_lengths, scene_cloud, write_simulation_report
    from reachwise.sim.scenarios import load_scenario
    from reachwise.sim.simulate import simulate

    name = p["scenario"]
    sc = load_scenario(name)
    duration = p["duration"]
    total = duration if duration is not None else sc.spec.duration
    logs = {}
    with ctx.progress(name) as bar:
        for avoid in (True, False):
            label = "avoidance" if avoid else "baseline"
            job = bar.add_task(label, total=round(total / sc.spec.dt))

            def tick(t: float, end: float, job: Any = job) -> None:
                ctx.check()
                bar.update(job, completed=round(min(t, end) / sc.spec.dt))

            logs[label] = simulate(sc, avoidance=avoid, duration=duration, progress=tick)
            bar.update(job, completed=round(total / sc.spec.dt))
    for label, log in logs.items():
        log.save(folder / label)
    summaries = {k: v.summary() for k, v in logs.items()}
    atomic_write(folder / "summary.json", json.dumps(summaries, indent=2))
    cloud = scene_cloud(sc)
    paths = save_figures(folder, logs["avoidance"], logs["baseline"], cloud)
    report = write_simulation_report(folder, sc, logs, {p.stem: p for p in paths}, cloud)
    res: dict[str, Any] = {"scenario": name, "scan_points": None if cloud is None else len(cloud)}
    lines = []
    for label, s in summaries.items():
        n = sum(g["reached_at"] is not None for g in s["goals"])
        coll = s["first_collision"]
        md = s["min_distance"]
        legs = [x[1] for r in logs[label].robots for x in leg_lengths(logs[label], r)]
        res[label] = {
            "goals": len(s["goals"]),
            "goals_reached": n,
            "reached_at": [g["reached_at"] for g in s["goals"]],
            "min_distance_m": md,
            "first_collision_s": coll,
            "first_collision_pair": s["first_collision_pair"],
            "legs_m": legs,
            "stalls": len(s["stalls"]),
        }
        lines.append(
            f"{label}: goals {n}/{len(s['goals'])}, min distance "
            + ("n/a" if md is None else f"{md * 100:.1f} cm")
            + ", "
            + (
                "no collision"
                if coll is None
                else f"collides at {coll:.2f} s ({s['first_collision_pair']})"
            )
        )
    lines.append(f"report: {report}")
    rel = _rel(ctx, report)
    return StageOutput(res, files=(rel,), lines=tuple(lines), report=rel)


def _kinematics(ctx: Ctx, folder: Path, p: dict[str, Any]) -> StageOutput:
    from reachwise.io.robot_file import load_robot
    from reachwise.kinematics.indices import lci

    rng = np.random.default_rng(ctx.seed)
    m = p["targets"]
    table = Table(title=f"IK of {m} random reachable targets per robot (tolerance 1 µm, 1 µrad)")
    for col in ("robot", "DOF", "task", "solved", "worst error m / rad", "IK ms", "LCI mean / min"):
        table.add_column(col, justify="right")
    rows: dict[str, Any] = {}
    for name in ("panda", "puma560", "sb60", "hiab-xs033"):
        robot = load_robot(name)
        Q = rng.uniform(robot.lower, robot.upper, (m, robot.n))
        mask = None if robot.actuated.sum() >= 6 else 3
        solved, ep, eo, times = 0, 0.0, 0.0, []
        for T in robot.fk(Q):
            ctx.check()
            t = time.perf_counter()
            res = robot.ik(T, mask=mask, rng=rng)
            times.append(time.perf_counter() - t)
            solved += res.success
            ep, eo = max(ep, res.position_error), max(eo, res.orientation_error)
        lcis = np.asarray(lci(robot, Q, rows=None if mask is None else [0, 1, 2]))
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
        rows[name] = row
        cond = f"{row['lci_mean']:.3f} / {row['lci_min']:.0e}"
        table.add_row(
            name,
            str(robot.n),
            f"{row['task_dims']}-D",
            f"{solved}/{m}",
            f"{ep:.0e} / {eo:.0e}",
            f"{row['median_ik_ms']:.2f}",
            cond,
        )
    ctx.console.print(table)
    return StageOutput(rows)


def _distance(ctx: Ctx, folder: Path, p: dict[str, Any]) -> StageOutput:
    import trimesh

    from reachwise.distance import PairQuery, closest_points
    from reachwise.geometry.cloud import sample_mesh_surface
    from reachwise.geometry.scan_scene import scan_scene
    from reachwise.kinematics.transforms import pose_from_xyz_rpy
    from reachwise.sim.p5_scenes import p5_floor_obstacle

    _, env = scan_scene(p5_floor_obstacle(), np.random.default_rng(ctx.seed))
    part = sample_mesh_surface(trimesh.creation.box((0.6, 0.4, 0.3)), n=1000, seed=ctx.seed)
    rng = np.random.default_rng(ctx.seed)
    query = PairQuery(part, env, margin=0.5)
    lo, hi = env.bounds
    agree, times, at_risk = 0, [], 0
    m = p["queries"]
    for _ in range(m):
        ctx.check()
        xyz = rng.uniform(lo, hi) + np.array([0.0, 0.0, rng.uniform(0.2, 1.0)])
        pose = pose_from_xyz_rpy(xyz, rng.uniform(-np.pi, np.pi, 3))
        t = time.perf_counter()
        fast = query(pose_a=pose)
        times.append(time.perf_counter() - t)
        ref = closest_points(part, env, pose_a=pose, margin=0.5, strategy="brute")
        at_risk += not ref.no_risk
        agree += fast.no_risk == ref.no_risk and (
            fast.no_risk or abs(fast.distance - ref.distance) <= 1e-9
        )
    med = float(np.median(times) * 1e6)
    figures = {
        "scan_points": len(env),
        "queries": m,
        "within_margin": at_risk,
        "agree_with_brute": agree,
        "median_query_us": med,
    }
    line = (
        f"scan: {len(env)} points (floor + obstacle, with the occlusion gap); "
        f"part: {len(part)} points; {m} random poses, margin 0.5 m: {at_risk} "
        f"within it; default strategy equals brute force on {agree}/{m}; "
        f"median query {med:.0f} µs"
    )
    return StageOutput(figures, lines=(line,))


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
