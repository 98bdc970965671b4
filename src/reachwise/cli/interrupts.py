"""Ctrl-C honoured between compiled calls, never inside one.

A numba kernel that returns a named tuple builds it by calling the tuple's Python
``__new__``. Python runs a signal handler at the next bytecode it executes, which may
be that ``__new__``: a :class:`KeyboardInterrupt` raised there leaves numba with a
half-built result and the process dies with SIGSEGV (numba 0.68), losing every result
not yet written. So while a command runs compiled code, SIGINT is only recorded
(:func:`deferred_interrupts`); the command asks between calls whether to stop
(:attr:`Interrupts.requested`), or passes :meth:`Interrupts.check` to a driver that
calls it between its steps, where raising is safe.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

__all__ = ["Interrupts", "deferred_interrupts"]


class Interrupts:
    """The Ctrl-C received while :func:`deferred_interrupts` is active."""

    def __init__(self) -> None:
        #: SIGINTs received by the handler.
        self.received = 0
        self._stopped = False
        self._raised = False

    def record(self, signum: int, frame: FrameType | None) -> None:
        """The SIGINT handler: count, never raise."""
        self.received += 1

    def stop(self) -> None:
        """Mark a stop that Python code raised itself (a :class:`KeyboardInterrupt`
        that reached the command without the handler)."""
        self._stopped = True

    @property
    def requested(self) -> bool:
        """Whether the command was asked to stop."""
        return self.received > 0 or self._stopped

    def check(self) -> None:
        """Raise :class:`KeyboardInterrupt` if a stop was asked — once: a second Ctrl-C
        while the first is handled (results being written) changes nothing."""
        if self.requested and not self._raised:
            self._raised = True
            raise KeyboardInterrupt


@contextmanager
def deferred_interrupts() -> Iterator[Interrupts]:
    """SIGINT recorded in the yielded :class:`Interrupts` instead of raising, until the
    block ends; then the previous handler is restored — unless a SIGINT was received:
    the command is then ending (exit code 130) and a further Ctrl-C during its exit must
    neither raise nor kill it, so the recording handler stays and SIGINT is blocked (the
    interpreter's finalization restores the default action, which would end the
    process with SIGINT instead of 130).

    Outside the main thread (where Python cannot set handlers) and where SIGINT is
    ignored (a background job) nothing is installed and nothing is ever received.
    """
    state = Interrupts()
    if (
        threading.current_thread() is not threading.main_thread()
        or signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    ):
        yield state
        return
    previous = signal.signal(signal.SIGINT, state.record)
    try:
        yield state
    finally:
        if not state.received:
            signal.signal(signal.SIGINT, previous)
        else:  # the interpreter's finalization resets handlers: block it at the OS level
            signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
