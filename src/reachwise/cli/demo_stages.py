"""The stages of ``reachwise demo`` (see :mod:`reachwise.cli.demo`): each writes its
outputs into its folder and returns its key figures, the files it wrote, the lines it
prints and its report (:class:`StageOutput`). A stage asks ``ctx.check()`` between its
steps, where a Ctrl-C may end it."""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from reachwise.io.atomic import atomic_write


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


def rel(ctx: Ctx, p: Path) -> str:
    """``p`` relative to the demo folder."""
    return str(p.relative_to(ctx.out))


def task(ctx: Ctx, folder: Path, p: dict[str, Any]) -> StageOutput:
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
    return StageOutput(figures, files=(rel(ctx, path),), lines=(line,))


def synthesis(ctx: Ctx, folder: Path, p: dict[str, Any]) -> StageOutput:
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
        best_line(d),
        *objective_lines(d),
        f"report: {report}",
    )
    return StageOutput(
        figures,
        files=(rel(ctx, report), rel(ctx, folder / "design.yaml")),
        lines=lines,
        report=rel(ctx, report),
    )


def best_line(d: dict[str, Any]) -> str:
    """The best run from its random start design to its final design, for the console."""
    b = d["best"]
    return (
        f"best run (seed {d['best_seed']}): {b['reached']}/{d['task_points']} reached; "
        f"from its random start design to the final design: GCI {b['gci_initial']:.4f} → "
        f"{b['gci']:.4f}, KCI {b['kci_initial']:.4f} → {b['kci']:.4f}"
    )


def objective_lines(d: dict[str, Any]) -> list[str]:
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


def topology(ctx: Ctx, folder: Path, p: dict[str, Any]) -> StageOutput:
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
        f"{cfg.top} on all {len(task)}; {cfg.runs} runs each ({data['new_items']} run now"
        + (
            f", {result.stale_items} replacing runs of other code in sweep.db)"
            if result.stale_items
            else ")"
        )
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
    path = rel(ctx, report)
    return StageOutput(figures, files=(path,), lines=tuple(lines), report=path)


def simulate(ctx: Ctx, folder: Path, p: dict[str, Any]) -> StageOutput:
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
    path = rel(ctx, report)
    return StageOutput(res, files=(path,), lines=tuple(lines), report=path)


def kinematics(ctx: Ctx, folder: Path, p: dict[str, Any]) -> StageOutput:
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


def distance(ctx: Ctx, folder: Path, p: dict[str, Any]) -> StageOutput:
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
