"""In-process Ctrl-C tests: an interrupted command leaves SIGINT blocked at the OS level
and its recording handler installed (``reachwise.cli.interrupts``: the process is
ending), which would swallow the next test's SIGINT. :func:`restored_sigint` puts the
handler and the signal mask back, discarding a SIGINT still pending."""

from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def restored_sigint() -> Iterator[None]:
    """Run the block with Python's own Ctrl-C handler (as in a terminal: a test runner's
    worker, e.g. pytest-xdist's, may ignore SIGINT, and a command that finds SIGINT
    ignored runs as a background job that no Ctrl-C reaches), then restore SIGINT's
    handler and unblock it (a pending SIGINT is dropped while the signal is ignored)."""
    handler = signal.getsignal(signal.SIGINT)
    blocked = signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, [])
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        if not blocked:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
        signal.signal(signal.SIGINT, handler)
