"""The ``reachwise`` command's entry point (also ``python -m reachwise``): Ctrl-C from
the first moment on ends it with exit code 130 and one line, never a traceback.

The command line's modules and the compiled kernels they load take a second or more
to import. This module imports nothing of reachwise before its SIGINT handler is in
place, so a Ctrl-C during that start-up is caught like any later one. The handler
raises :class:`KeyboardInterrupt` for the first SIGINT only: a second Ctrl-C while the
first is being handled is not a second traceback. Once the modules are loaded Python's
own handler is back, and each command decides what a Ctrl-C means
(``reachwise.cli.main``, ``reachwise.cli.interrupts``).

A launcher that ignores SIGINT (a shell's background job) is obeyed: nothing is
installed. A SIGINT the launcher blocked until now (a test that must not lose one to
the interpreter's own start-up) is delivered once the handler is in place.
"""

from __future__ import annotations

import os
import signal
import sys
from types import FrameType

#: Exit code of a command ended by Ctrl-C (128 + SIGINT, as a shell reports it).
INTERRUPTED = 130


class _FirstInterrupt:
    """SIGINT handler raising :class:`KeyboardInterrupt` once, ignoring later ones."""

    def __init__(self) -> None:
        self.received = 0

    def __call__(self, signum: int, frame: FrameType | None) -> None:
        self.received += 1
        if self.received == 1:
            raise KeyboardInterrupt


def main() -> None:
    """Run the ``reachwise`` command (``reachwise.cli.main``) with start-up guarded
    against Ctrl-C."""
    guard = signal.getsignal(signal.SIGINT) is signal.default_int_handler
    if guard:
        signal.signal(signal.SIGINT, _FirstInterrupt())
    try:
        if guard:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
        from reachwise.cli import main as run_command

        if guard:
            signal.signal(signal.SIGINT, signal.default_int_handler)
        run_command()
    except KeyboardInterrupt:  # before the command's own handling began
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        print("interrupted", file=sys.stderr, flush=True)
        _exit_interrupted()
    except SystemExit as exc:
        if exc.code == INTERRUPTED:
            _exit_interrupted()
        raise


def _exit_interrupted() -> None:
    """End with :data:`INTERRUPTED`, not by SystemExit: a KeyboardInterrupt raised inside
    code that an extension ran while importing (PyRun_String) is marked unhandled even
    when caught, and the interpreter then ends itself with SIGINT (exit -2) whatever
    code it was given. The command has written its files (atomically) already."""
    import logging

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(INTERRUPTED)


if __name__ == "__main__":
    main()
