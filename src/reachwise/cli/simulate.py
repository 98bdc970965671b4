"""``reachwise simulate``: run a scenario (built-in or file), write logs and figures."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TaskID, TextColumn, TimeElapsedColumn

from reachwise.cli._help import builtins
from reachwise.cli._options import cli, typed_command
from reachwise.io.atomic import atomic_write

if TYPE_CHECKING:
    from reachwise.server.client import ServerOptions
    from reachwise.sim.log import SimulationLog
    from reachwise.sim.plant import PlantName
    from reachwise.sim.world import SceneFactory


@dataclass(frozen=True)
class ScenarioRun:
    """The runs to make: the ``scenario`` (a built-in name or a file), also without
    avoidance (``baseline``), for ``duration`` seconds (``None``: the scenario's), on
    which ``plant``, with the ``escape`` planner on, off or as the scenario says."""

    #: Built-in scenario name or scenario file path.
    scenario: str = cli(
        typer.Argument(
            ...,
            help=f"Built-in scenario ({builtins('scenarios')}) or a scenario YAML file.",
        )
    )
    #: Also run without avoidance.
    baseline: bool = cli(
        typer.Option(False, "--baseline", help="Also run the same controller without avoidance.")
    )
    #: Simulated time (s); ``None``: the scenario's.
    duration: float | None = cli(typer.Option(None, "--duration", min=0.0, help="Override (s)."))
    #: ``"scenario"`` or ``"mujoco"``.
    plant: str = cli(
        typer.Option(
            "scenario",
            "--plant",
            help="scenario (each robot's own kinematic/hydraulic plant) or mujoco (rigid-body "
            "dynamics with velocity servos; the sim extra), compared with the scenario's plant.",
        )
    )
    #: Escape planning on or off; ``None``: the scenario's.
    escape: bool | None = cli(
        typer.Option(
            None,
            "--escape/--no-escape",
            help="When a robot stalls in a local minimum, plan a way out with OMPL RRT-Connect "
            "(the plan extra) and follow it, then resume (default: the scenario's escape: "
            "setting).",
        )
    )


@dataclass(frozen=True)
class ServerLink:
    """Where the distance queries run: in process (``server`` ``None``) or on the
    collision server at address ``server``, with a per-tick reply deadline (s), a
    timeout (s) to wait for it to be ready and its CURVE key folder."""

    #: Collision server address, e.g. tcp://127.0.0.1:5590; ``None``: in process.
    server: str | None = cli(
        typer.Option(
            None,
            "--server",
            help="Run the distance queries on the collision server at this address (`reachwise "
            "serve`), e.g. tcp://127.0.0.1:5590; its scene is replaced by the scenario's. A "
            "reply later than --server-deadline is missing data: the robots stop safely.",
        )
    )
    #: Per-tick reply deadline (s).
    server_deadline: float = cli(
        typer.Option(
            0.1, "--server-deadline", min=0.0001, help="Per-tick reply deadline on --server (s)."
        )
    )
    #: How long to wait for the server to be ready (s).
    server_timeout: float = cli(
        typer.Option(
            30.0,
            "--server-timeout",
            min=0.0,
            help="How long to wait for --server to be ready (s); then exit code 4.",
        )
    )
    #: CURVE key folder; ``None``: no encryption.
    server_keys: Path | None = cli(
        typer.Option(
            None, "--server-keys", help="CURVE key folder (`reachwise serve keygen`) for --server."
        )
    )


@dataclass(frozen=True)
class SimulationOutput:
    """What the command writes and shows: the ``out`` folder (logs, summary,
    figures, report), PNG ``figures``, JSON on stdout (``json_out``), a live browser
    viewer (``view``) and a ROS 2 ``bag`` of the avoidance run."""

    #: Output folder; ``None``: nothing written.
    out: Path | None = cli(
        typer.Option(None, "--out", help="Folder for log.npz, log.csv, summary.json and figures.")
    )
    #: Write PNG figures.
    figures: bool = cli(typer.Option(True, "--figures/--no-figures", help="Write PNG figures."))
    #: Print the summary as JSON.
    json_out: bool = cli(typer.Option(False, "--json", help="Print the summary as JSON."))
    #: Watch the runs live in the browser viewer.
    view: bool = cli(
        typer.Option(
            False,
            "--view",
            help="Watch each run live in the browser viewer (127.0.0.1:8080 or the next free "
            "port), in real time, then replay the logs there; Ctrl-C stops it.",
        )
    )
    #: ROS 2 bag file of the avoidance run; ``None``: none.
    bag: Path | None = cli(
        typer.Option(
            None,
            "--bag",
            help="Also write the avoidance run (joint states, the cameras' depth images, "
            "CameraInfo and clouds, TF) as a bag: .bag for ROS 1, .mcap for MCAP, else ROS 2 "
            "sqlite3 (the ros extra); `reachwise replay BAG --scenario SCENARIO` reads it back.",
        )
    )


@typed_command(
    order=(
        "scenario",
        "baseline",
        "out",
        "duration",
        "figures",
        "json_out",
        "plant",
        "server",
        "server_deadline",
        "server_timeout",
        "server_keys",
        "view",
        "bag",
        "escape",
    )
)
def simulate(run: ScenarioRun, link: ServerLink, output: SimulationOutput) -> None:
    """Simulate a scenario with collision avoidance (thesis §3.3, P-III/P-IV/P-V).

    Ctrl-C (once or more) ends the run between two ticks: the ticks finished so far are
    written to --out as a valid log (``extras.interrupted`` in its summary), the runs
    finished before it in full, and the command exits with 130.
    """
    from reachwise.cli.interrupts import deferred_interrupts
    from reachwise.errors import InputError, check_choice
    from reachwise.sim.plant import PLANT_NAMES
    from reachwise.sim.scenarios import load_scenario

    plant_name = check_choice(run.plant, PLANT_NAMES, source="--plant", kind="plant")
    if plant_name == "mujoco":
        from reachwise.sim.mujoco_model import require_mujoco

        require_mujoco()  # a clear error naming the missing extra, before any work
    if output.bag is not None and output.bag.exists():
        raise InputError(str(output.bag), "--bag", "exists already; not overwriting a recording")
    console = Console(stderr=True)
    with deferred_interrupts() as interrupts:
        sc = load_scenario(run.scenario)
        if output.out is not None:  # computed helpers (automatic self-collision pairs) cached there
            sc.cache_dir = output.out
        make_scene = None
        if link.server is not None:
            from reachwise.server.client import ServerOptions

            make_scene = _server_scene(
                ServerOptions(
                    link.server, deadline=link.server_deadline, keys=link.server_keys,
                    ready_timeout=link.server_timeout,
                )
            )  # fmt: skip
        live = None
        if output.view:
            from reachwise.viz.live import LiveSession

            live = LiveSession(sc, echo=console.print)
        modes = [True, False] if run.baseline else [True]
        runs: list[tuple[bool, PlantName]] = [(m, plant_name) for m in modes]
        if plant_name == "mujoco":
            runs.append((True, "scenario"))
        opts = _RunOptions(run.duration, make_scene, run.escape, output.bag, live, output.json_out)
        logs, stopped = _run_all(sc, runs, opts, console, interrupts.check)
        if stopped is not None:
            _keep_interrupted(sc, logs, stopped, output.out, console, output.json_out)
            raise typer.Exit(130)
        data = _write(sc, logs, output.out, output.figures)
        stop = interrupts.requested  # Ctrl-C while the results were written: they are
    if output.json_out:
        typer.echo(json.dumps(data, indent=2))
    else:
        _print(data, console)
    if live is not None:
        if stop:
            live.stop()
            return
        try:
            live.replay(logs)  # until Ctrl-C
        except KeyboardInterrupt:  # while it switched to the playback: the runs are written
            live.stop()


@dataclass(frozen=True)
class _RunOptions:
    """How each run of the command goes: its ``duration`` override (s, ``None``: the
    scenario's), the distance scene factory (``None``: in process), the ``escape``
    override, the ``bag`` file the avoidance run records, the live viewer session
    and whether the progress bar is off (``quiet``)."""

    duration: float | None
    make_scene: SceneFactory | None
    escape: bool | None
    bag: Path | None
    live: Any
    quiet: bool


def _label(avoid: bool, kind: str, plant_name: str) -> str:
    if plant_name == "mujoco" and kind != plant_name:
        return "reference"  # the same scenario on its own plant, for comparison
    return "avoidance" if avoid else "baseline"


def _run_all(
    sc: Any, runs: list[tuple[bool, PlantName]], opts: _RunOptions, console: Console,
    check: Callable[[], None],
) -> tuple[dict[str, SimulationLog], str | None]:  # fmt: skip
    """Each run in turn (``(avoidance, plant)``); ``check`` is called between ticks and
    may raise :class:`KeyboardInterrupt` to stop. The logs by label (an interrupted
    run's log holds its finished ticks) and the label of the interrupted run, if any."""
    from reachwise.sim.bag_recorder import BagRecorder
    from reachwise.sim.simulate import SimulationInterrupted
    from reachwise.sim.simulate import simulate as run

    logs: dict[str, SimulationLog] = {}
    total = opts.duration if opts.duration is not None else sc.spec.duration
    with Progress(
        TextColumn("[bold]{task.description}"), BarColumn(), TextColumn("{task.fields[t]}"),
        TimeElapsedColumn(), console=console, disable=opts.quiet,
    ) as bar:  # fmt: skip
        for avoid, kind in runs:
            label = _label(avoid, kind, runs[0][1])
            job = bar.add_task(f"{sc.name} {label}", total=total, t="")

            def tick(t: float, end: float, job: TaskID = job) -> None:
                check()
                if round(t / sc.spec.dt) % 10 == 0:
                    bar.update(job, completed=min(t, end), t=f"{t:6.2f} s")

            recorder = (
                BagRecorder(opts.bag) if opts.bag is not None and label == "avoidance" else None
            )
            live = opts.live
            try:
                check()
                logs[label] = run(
                    sc, avoidance=avoid, duration=opts.duration, progress=tick, plant=kind,
                    make_scene=opts.make_scene, escape=opts.escape, recorder=recorder,
                    on_tick=live.hook(avoid, label) if live is not None else None,
                )  # fmt: skip
            except SimulationInterrupted as exc:
                logs[label] = exc.log
                return logs, label
            except KeyboardInterrupt:  # before the run's first tick
                return logs, label
            finally:
                if recorder is not None:
                    recorder.close()
            bar.update(job, completed=total)
    return logs, None


def _keep_interrupted(
    sc: Any, logs: dict[str, SimulationLog], stopped: str, out: Path | None, console: Console,
    json_out: bool,
) -> None:  # fmt: skip
    """Write what an interrupted command finished: each log with at least one tick (the
    interrupted run's up to its last finished tick) and ``summary.json``; no figures,
    no report. Say what was kept and how to run it whole."""
    kept = {label: log for label, log in logs.items() if log.t.size}
    data = {label: log.summary() for label, log in kept.items()}
    data["interrupted"] = stopped  # type: ignore[assignment]
    if out is not None and kept:
        for label, log in kept.items():
            log.save(out / label)
        atomic_write(out / "summary.json", json.dumps(data, indent=2))
    t = logs[stopped].t[-1] if stopped in logs and logs[stopped].t.size else None
    where = f" at t = {t:.2f} s" if t is not None else " before its first tick"
    if out is None:
        what = "nothing written (no --out)"
    elif kept:
        what = (
            "kept "
            + ", ".join(f"{out / label}/ ({log.t.size} ticks)" for label, log in kept.items())
            + f" and {out / 'summary.json'}"
        )
    else:
        what = "nothing written"
    console.print(
        f"interrupted during the {stopped} run of {sc.name}{where}: {what}; "
        "run the same command to simulate it whole"
    )
    if json_out:
        typer.echo(json.dumps(data, indent=2))


def _write(
    sc: Any, logs: dict[str, SimulationLog], out: Path | None, figures: bool
) -> dict[str, Any]:
    """The summary of the finished runs; with ``out``, their logs, figures, summary and
    HTML report written there."""
    main = logs["avoidance"]
    base = logs.get("baseline")
    ref = logs.get("reference")
    if ref is not None:
        from reachwise.sim.mujoco_plant import plant_comparison

        main.extras["comparison"] = plant_comparison(main, ref)
    data: dict[str, Any] = {"avoidance": main.summary()}
    if base is not None:
        data["baseline"] = base.summary()
    if ref is not None:
        data["reference"] = ref.summary()
    if out is None:
        return data
    for label, log in logs.items():
        log.save(out / label)
    cloud, pngs = None, None
    if figures:
        from reachwise.report.sim_plots import save_figures
        from reachwise.report.simulate import scene_cloud

        cloud = scene_cloud(sc)
        pngs = {p.stem: p for p in save_figures(out, main, base, cloud)}
    atomic_write(out / "summary.json", json.dumps(data, indent=2))
    data["out"] = str(out)
    from reachwise.report.simulate import write_simulation_report

    report = write_simulation_report(out, sc, logs, pngs or False, cloud)
    data["report"] = str(report)
    return data


def _print(data: dict, console: Console) -> None:  # type: ignore[type-arg]
    out = Console()
    for label in ("avoidance", "baseline", "reference"):
        s = data.get(label)
        if s is None:
            continue
        plant = s.get("extras", {}).get("plant", "scenario")
        if plant != "scenario" or label == "reference":
            label = f"{label} ({plant} plant)"
        n_reached = sum(g["reached_at"] is not None for g in s["goals"])
        md = s["min_distance"]
        md_s = f"{md * 100:.1f} cm" if md is not None else "n/a"
        if "min_true_distance" in s:  # objects only sensors see: their true surfaces
            tmd = s["min_true_distance"]
            md_s += f" (sensed); true {tmd * 100:.1f} cm" if tmd is not None else ""
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
        for ev in s["events"]:
            if ev["kind"] in ("planning", "escaped", "escape_failed"):
                out.print(f"  {ev['kind']} at {ev['t']:.2f} s ({ev['robot']}): {ev['text']}")
        _print_tracking(s.get("extras", {}), out)
    if "out" in data:
        out.print(f"wrote {data['out']}/")
        out.print(f"report: {data['report']}")


def _print_tracking(extras: dict, out: Console) -> None:  # type: ignore[type-arg]
    """The MuJoCo plant's tracking error and its comparison with the scenario's plant."""
    for robot, tr in extras.get("tracking", {}).items():
        if not tr.get("ticks"):
            continue
        line = (
            f"  {robot}: servo tau {tr['servo_time_constant'] * 1e3:.0f} ms, velocity error "
            f"rms {tr['velocity_error_rms']:.4f} max {tr['velocity_error_max']:.4f}, beyond "
            f"first-order {tr['first_order_error_max']:.4f}, position lag max "
            f"{tr['position_lag_max']:.4f} (first-order bound {tr['position_lag_bound']:.4f})"
        )
        if "passive_swing_max" in tr:
            line += f", passive swing max {math.degrees(tr['passive_swing_max']):.1f} deg"
        out.print(line)
    comp = extras.get("comparison")
    if comp is None:
        return
    for robot, c in comp["robots"].items():

        def fmt(v: float | None) -> str:
            return "n/a" if v is None else f"{v * 100:.1f} cm"

        def times(ts: list[float | None]) -> str:
            return ", ".join("-" if t is None else f"{t:.2f}" for t in ts) + " s"

        out.print(
            f"  {robot} vs {comp['plant']} plant: goals at {times(c['goals_reached_at'])} "
            f"(reference {times(c['reference_goals_reached_at'])}), min distance "
            f"{fmt(c['min_distance'])} (reference {fmt(c['reference_min_distance'])}), "
            f"max joint difference {c['joint_difference_max']:.4f}, max tool difference "
            f"{fmt(c['tool_difference_max'])}"
        )


def _server_scene(link: ServerOptions) -> SceneFactory:
    """The scene of a simulation on the collision server ``link``: a client that owns
    the server's scene, stamped with the simulation's clock."""
    import time

    from reachwise.server.client import owned_scene

    def make(clock: Callable[[], float] | None) -> Any:
        return owned_scene(link, clock or time.monotonic)

    return make
