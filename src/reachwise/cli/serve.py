"""``reachwise serve``: run the collision server; ``reachwise serve keygen DIR``: CURVE keys.

The collision server of P-IV/P-V (thesis §3.1, P-III §4.1 Fig. 2) as a process of its
own: it keeps the clouds of the initialization phase (P-V Table 1), takes joint states
and scans, and answers all watched pairs every control cycle
(:mod:`reachwise.server.service`). It binds a loopback or ``ipc://`` address by default;
any other address needs CURVE keys (``--keys DIR`` from ``reachwise serve keygen DIR``)
or an explicit ``--insecure`` (:mod:`reachwise.server.security`). With ``--state DIR``
the scene survives a crash or restart. SIGINT or SIGTERM stop it cleanly.

Run it as ``reachwise serve`` or ``python -m reachwise.cli.serve``.
"""

from __future__ import annotations

import logging
import signal
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import typer

from reachwise.cli._options import cli, typed_command
from reachwise.server.security import DEFAULT_BIND

app = typer.Typer(
    help="Run the collision server (ZeroMQ + msgpack), or make its CURVE keys.",
    invoke_without_command=True,
    no_args_is_help=False,
    pretty_exceptions_enable=False,
    add_completion=False,
)


@dataclass(frozen=True)
class ServerEndpoint:
    """Where the server listens and who may talk to it: the ``bind`` endpoint, the
    CURVE ``keys`` folder, ``insecure`` (a non-local bind without CURVE) and the file
    the bound endpoint is written to (``endpoint_file``)."""

    #: ZeroMQ endpoint, e.g. tcp://127.0.0.1:5590 (PORT ``*``: any free port).
    bind: str = cli(
        typer.Option(
            DEFAULT_BIND,
            "--bind",
            help="Endpoint: tcp://127.0.0.1:PORT (PORT * = any free), ipc:///path, or with "
            "--keys/--insecure any tcp address.",
        )
    )
    #: CURVE key folder; ``None``: no encryption (local binds only).
    keys: Path | None = cli(
        typer.Option(None, "--keys", help="CURVE key folder from `reachwise serve keygen DIR`.")
    )
    #: Allow a non-local bind without CURVE.
    insecure: bool = cli(
        typer.Option(
            False, "--insecure", help="Allow a non-local bind without CURVE (not recommended)."
        )
    )
    #: File the bound endpoint is written to; ``None``: none.
    endpoint_file: Path | None = cli(
        typer.Option(None, "--endpoint-file", help="Write the bound endpoint to this file.")
    )


@dataclass(frozen=True)
class ServerSettings:
    """How the server answers: the distance ``strategy``, the size cap of one message
    (``max_message_mb``, MiB), the most points in one cloud, the ZeroMQ I/O threads
    and the SCHED_FIFO ``priority`` (1-99; ``None``: normal priority)."""

    #: Distance strategy: default, thesis or brute.
    strategy: str = cli(
        typer.Option("default", "--strategy", help="Distance strategy: default, thesis or brute.")
    )
    #: Size cap of one message (MiB).
    max_message_mb: float = cli(
        typer.Option(64.0, "--max-message-mb", help="Size cap of one message, MiB.")
    )
    #: Most points in one cloud.
    max_cloud_points: int = cli(
        typer.Option(2_000_000, "--max-cloud-points", help="Most points in one cloud.")
    )
    #: SCHED_FIFO priority (1-99); ``None``: normal priority.
    priority: int | None = cli(
        typer.Option(
            None,
            "--priority",
            min=1,
            max=99,
            help="Serve queries under SCHED_FIFO at this priority (Linux; needs root, "
            "CAP_SYS_NICE or an rtprio limit): the request thread and ZeroMQ's I/O "
            "threads; cloud indexing stays at a low normal priority.",
        )
    )
    #: ZeroMQ I/O threads.
    io_threads: int = cli(
        typer.Option(
            2, "--io-threads", min=1, help="ZeroMQ I/O threads (connections are spread over them)."
        )
    )


@dataclass(frozen=True)
class ServerLifetime:
    """What the server keeps and for how long: the ``state`` directory (the scene
    survives restarts; ``None``: not kept), ``max_runtime`` (s; ``None``: until
    SIGINT/SIGTERM) and ``verbose`` logging."""

    #: State directory; ``None``: the scene is not kept.
    state: Path | None = cli(
        typer.Option(None, "--state", help="State directory: the scene survives restarts.")
    )
    #: Stop by itself after this many seconds; ``None``: never.
    max_runtime: float | None = cli(
        typer.Option(None, "--max-runtime", help="Stop by itself after this many seconds.")
    )
    #: Log every state change.
    verbose: bool = cli(typer.Option(False, "--verbose", "-v", help="Log every state change."))


@app.callback(invoke_without_command=True)
@typed_command(
    order=(
        "bind", "state", "keys", "insecure", "strategy", "max_message_mb", "max_cloud_points",
        "max_runtime", "endpoint_file", "verbose", "priority", "io_threads",
    )
)  # fmt: skip
def serve(
    ctx: typer.Context, endpoint: ServerEndpoint, settings: ServerSettings, life: ServerLifetime
) -> None:
    """Run the collision server until SIGINT/SIGTERM (or --max-runtime)."""
    if ctx.invoked_subcommand is not None:
        return
    logging.basicConfig(
        level=logging.INFO if life.verbose else logging.WARNING,
        format="%(asctime)s reachwise-serve %(levelname)s %(message)s",
        stream=sys.stderr,
    )
    server, priority = _server(endpoint, settings, life)
    bound = server.start()
    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        if endpoint.endpoint_file is not None:
            from reachwise.io.atomic import atomic_write

            atomic_write(endpoint.endpoint_file, bound.encode())
        for sig in previous:
            signal.signal(sig, lambda *_: server.stop())
        typer.echo(
            f"reachwise serve: listening on {bound} "
            f"(CURVE {'on' if server.plan.curve else 'off'}, "
            f"state {life.state if life.state is not None else 'not kept'}, "
            f"{f'SCHED_FIFO {priority}' if priority is not None else 'normal priority'})"
        )
        sys.stdout.flush()
        _serve(server, priority, life.max_runtime)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        server.close()
    typer.echo("reachwise serve: stopped")


def _server(
    endpoint: ServerEndpoint, settings: ServerSettings, life: ServerLifetime
) -> tuple[Any, int | None]:
    """The collision server of the options (not started) and the SCHED_FIFO priority
    it gets (``None`` when not asked or refused, with a warning)."""
    from reachwise.distance.engine import STRATEGIES
    from reachwise.errors import check_choice
    from reachwise.runtime.realtime import fifo_refusal
    from reachwise.server.protocol import Limits
    from reachwise.server.transport import CollisionServer

    try:
        limits = Limits(int(settings.max_message_mb * 2**20), settings.max_cloud_points)
    except ValueError as exc:
        typer.secho(f"error: {exc}", err=True, fg=typer.colors.RED)
        raise typer.Exit(2) from None
    priority = settings.priority
    if priority is not None and (refused := fifo_refusal(priority)):
        typer.secho(
            f"warning: --priority {priority}: SCHED_FIFO {refused}; serving at normal priority",
            err=True,
            fg=typer.colors.YELLOW,
        )
        priority = None
    server = CollisionServer(
        endpoint.bind,
        life.state,
        keys=endpoint.keys,
        insecure=endpoint.insecure,
        strategy=check_choice(settings.strategy, STRATEGIES, source="--strategy", kind="strategy"),
        limits=limits,
        io_threads=settings.io_threads,
        io_priority=priority,
    )
    if not server.plan.local and not server.plan.curve:
        typer.secho(
            f"warning: {endpoint.bind} is reachable from other machines WITHOUT encryption "
            "(--insecure)",
            err=True,
            fg=typer.colors.YELLOW,
        )
    return server, priority


def _serve(server: Any, priority: int | None, max_runtime: float | None) -> None:
    """Serve until stopped, under the real-time process settings."""
    from reachwise.runtime.realtime import realtime_settings

    # as for a 1 kHz loop (reachwise.runtime.realtime): what is loaded by now lives
    # as long as the process, so it is frozen out of the collector's sight (a full
    # collection takes microseconds instead of a 100 ms pause mid-tick) and handed
    # back on exit (called in-process: a test, an embedding); the request thread
    # under SCHED_FIFO (the indexing worker it starts later drops that), glibc's
    # freed memory kept and transparent huge pages off
    with realtime_settings(priority=priority):
        server.serve_forever(max_runtime)


@app.command("keygen")
def keygen(
    directory: Annotated[Path, typer.Argument(help="Folder for the key files.")],
    force: bool = typer.Option(False, "--force", help="Replace existing keys."),
) -> None:
    """Create CURVE key pairs for the server and a client, and the authorized/ folder."""
    from reachwise.server.security import keygen as make_keys

    paths = make_keys(directory, force=force)
    typer.echo(f"server public key  {paths['server']}  (give to clients)")
    typer.echo(f"server secret key  {paths['server_secret']}  (server only)")
    typer.echo(f"client key pair    {paths['client']}, {paths['client_secret']}")
    typer.echo(f"authorized clients {paths['authorized']}/  (copy more clients' .key here)")


def main() -> None:
    """Entry point of ``python -m reachwise.cli.serve``: errors as one line, with the
    exit code of their class (2 bad input, 4 the server cannot serve, e.g. its address)."""
    from reachwise.errors import ReachwiseError

    try:
        app()
    except ReachwiseError as exc:
        typer.secho(f"error: {exc}", err=True, fg=typer.colors.RED)
        raise SystemExit(exc.exit_code) from None


if __name__ == "__main__":
    main()
