"""The ``reachwise`` command. Each command group lives in its own module here."""

from __future__ import annotations

import typer

from reachwise._version import __version__
from reachwise.cli import bench, cloud, demo, replay, robot, serve, synth, task, topology, view
from reachwise.cli import simulate as sim_cli
from reachwise.cli._help import plain_help

app = typer.Typer(
    name="reachwise",
    help="Design serial manipulators from their task and move them without collisions.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    epilog="Exit codes: 0 success, 1 other error, 2 bad input, 3 missing optional package, "
    "4 collision server unavailable, 130 interrupted.",
)
app.add_typer(robot.app, name="robot")
app.add_typer(cloud.app, name="cloud")
app.add_typer(task.app, name="task")
app.command("synth")(synth.synth)
app.command("topology")(topology.topology)
app.command("simulate")(sim_cli.simulate)
app.add_typer(serve.app, name="serve")
app.command("bench")(bench.bench)
app.command("demo")(demo.demo)
app.command("scan")(cloud.scan)
app.command("view")(view.view)
app.command("replay")(replay.replay)
plain_help(app)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"reachwise {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(
        False, "--version", callback=_version, is_eager=True, help="Print the version."
    ),
) -> None:
    """reachwise: task-based manipulator design and real-time collision avoidance."""


def main() -> None:
    """Entry point: run the app; a :class:`~reachwise.errors.ReachwiseError` ends it with
    one line on stderr (``error: <message>``) and the error's exit code:

    ====  ===========================================================================
    code  meaning
    ====  ===========================================================================
    0     success
    1     any other reachwise error
    2     bad input: a file, field or argument (``InputError``, e.g. an unknown name)
    3     a missing optional package; the line says what to install
          (``MissingDependency``)
    4     an unavailable service: the collision server did not answer
          (``ServerUnavailable``)
    130   interrupted (Ctrl-C); finished work is kept
    ====  ===========================================================================

    A Ctrl-C that no command handles ends it with 130 and the line ``interrupted``.
    """
    from reachwise.errors import ReachwiseError

    try:
        app()
    except ReachwiseError as exc:
        typer.secho(f"error: {exc}", err=True, fg=typer.colors.RED)
        raise SystemExit(exc.exit_code) from None
    except KeyboardInterrupt:
        typer.secho("interrupted", err=True)
        raise SystemExit(130) from None
