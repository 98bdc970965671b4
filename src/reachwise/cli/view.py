"""``reachwise view``: the browser viewer (viser) on a robot, scenario or results."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import typer

from reachwise.cli._options import cli, typed_command
from reachwise.cli._robot_options import RobotFileOptions

if TYPE_CHECKING:
    from reachwise.kinematics.robot import Robot


@dataclass(frozen=True)
class ViewTarget:
    """What the viewer shows: ``path`` (a robot, scenario, output folder or results
    folder) and, for a log whose scenario is not built in, its ``scenario`` file."""

    #: Built-in name, robot or scenario file, or results folder.
    path: str = cli(
        typer.Argument(
            ...,
            help="A built-in robot or scenario name, a robot/scenario file, a simulation or "
            "synthesis output folder, or a folder of results (e.g. reachwise-demo/).",
        )
    )
    #: Scenario file of a log whose scenario is not built in; ``None``: built in.
    scenario: Path | None = cli(
        typer.Option(
            None, "--scenario", help="Scenario file of a log whose scenario is not built-in."
        )
    )


@dataclass(frozen=True)
class ViewerAddress:
    """Where the viewer serves: ``host`` address and ``port`` (the next free one if
    taken)."""

    #: Address to bind.
    host: str = cli(
        typer.Option("127.0.0.1", "--host", help="Address to bind (127.0.0.1: this machine only).")
    )
    #: Port (0-65535).
    port: int = cli(
        typer.Option(8080, "--port", min=0, max=65535, help="Port (the next free one if taken).")
    )


@dataclass(frozen=True)
class LiveView:
    """A live run of a scenario (``live``): also without avoidance (``baseline``),
    for ``duration`` seconds (``None``: the scenario's), at ``speed`` times real time
    (0: as fast as it runs)."""

    #: Run the scenario and watch it live, then replay it.
    live: bool = cli(
        typer.Option(
            False, "--live", help="PATH is a scenario: run it and watch it live, then replay it."
        )
    )
    #: Run without avoidance.
    baseline: bool = cli(
        typer.Option(False, "--baseline", help="With --live: run without avoidance (the baseline).")
    )
    #: Simulated time (s); ``None``: the scenario's.
    duration: float | None = cli(
        typer.Option(None, "--duration", min=0.0, help="With --live: override the scenario's (s).")
    )
    #: Times real time; 0: as fast as it runs.
    speed: float = cli(
        typer.Option(
            1.0, "--speed", min=0.0, help="With --live: times real time (0: as fast as it runs)."
        )
    )


@typed_command(
    order=(
        "path",
        "host",
        "port",
        "scenario",
        "live",
        "baseline",
        "duration",
        "speed",
        "tip",
        "package_dir",
        "lenient",
    )
)
def view(
    target: ViewTarget, address: ViewerAddress, live: LiveView, robot: RobotFileOptions
) -> None:
    """Open the viewer in the browser; Ctrl-C stops it.

    Shows a robot with joint sliders, a scenario's scene, the playback of a simulation
    log (play/pause, time slider, closest-point lines), a synthesis result (the
    configuration at each task point, points coloured by status), or a live simulation.
    """
    path, host, port = target.path, address.host, address.port
    if live.live:
        _live(path, host, port, not live.baseline, live.duration, live.speed)
        return
    if robot.given:  # a robot file loaded with options
        _robot(path, host, port, robot.load(path))
        return
    from reachwise.viz.viewer import serve_results

    serve_results(path, host=host, port=port, block=True, scenario=target.scenario, echo=typer.echo)


def _robot(path: str, host: str, port: int, robot: Robot) -> None:
    from reachwise.viz.modes import show_robot
    from reachwise.viz.viewer import Viewer

    def show(v: Viewer) -> None:
        show_robot(v, robot)

    viewer = Viewer(host, port)
    try:
        viewer.show_entries({Path(path).name: show})
    except BaseException:
        viewer.stop()
        raise
    typer.echo(f"viewer at {viewer.url} (Ctrl-C to stop)")
    viewer.wait()


def _live(
    scenario: str, host: str, port: int, avoidance: bool, duration: float | None, speed: float
) -> None:
    from reachwise.sim.scenarios import load_scenario
    from reachwise.viz.live import LiveRun
    from reachwise.viz.viewer import Viewer

    sc = load_scenario(scenario)
    viewer = Viewer(host, port)
    try:
        run = LiveRun(viewer, sc, avoidance, duration=duration, speed=speed)
        typer.echo(f"viewer at {viewer.url}: {sc.name} runs live, then replays (Ctrl-C to stop)")
        run.start(replay=True)
    except BaseException:
        viewer.stop()
        raise
    viewer.wait()
    if run.error is not None:
        raise run.error
