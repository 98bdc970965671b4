"""``reachwise view``: the browser viewer (viser) on a robot, scenario or results."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import typer

from reachwise.cli._robot_options import LENIENT, PACKAGE_DIRS, TIP, load_with_options

if TYPE_CHECKING:
    from reachwise.kinematics.robot import Robot


def view(
    path: str = typer.Argument(
        ...,
        help="A built-in robot or scenario name, a robot/scenario file, a simulation or "
        "synthesis output folder, or a folder of results (e.g. reachwise-demo/).",
    ),
    host: str = typer.Option(
        "127.0.0.1", "--host", help="Address to bind (127.0.0.1: this machine only)."
    ),
    port: int = typer.Option(
        8080, "--port", min=0, max=65535, help="Port (the next free one if taken)."
    ),
    scenario: Path | None = typer.Option(
        None, "--scenario", help="Scenario file of a log whose scenario is not built-in."
    ),
    live: bool = typer.Option(
        False, "--live", help="PATH is a scenario: run it and watch it live, then replay it."
    ),
    baseline: bool = typer.Option(
        False, "--baseline", help="With --live: run without avoidance (the baseline)."
    ),
    duration: float | None = typer.Option(
        None, "--duration", min=0.0, help="With --live: override the scenario's (s)."
    ),
    speed: float = typer.Option(
        1.0, "--speed", min=0.0, help="With --live: times real time (0: as fast as it runs)."
    ),
    tip: str | None = TIP,
    package_dir: list[Path] = PACKAGE_DIRS,
    lenient: bool = LENIENT,
) -> None:
    """Open the viewer in the browser; Ctrl-C stops it.

    Shows a robot with joint sliders, a scenario's scene, the playback of a simulation
    log (play/pause, time slider, closest-point lines), a synthesis result (the
    configuration at each task point, points coloured by status), or a live simulation.
    """
    if live:
        _live(path, host, port, not baseline, duration, speed)
        return
    if tip is not None or package_dir or lenient:  # a robot file loaded with options
        _robot(path, host, port, load_with_options(path, tip, package_dir, lenient))
        return
    from reachwise.viz.viewer import serve_results

    serve_results(path, host=host, port=port, block=True, scenario=scenario, echo=typer.echo)


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
