"""Ctrl-C and SIGTERM between two communication steps, and a run's time limit.

A pythonfmu FMU runs its Python code in this interpreter, so an interrupt raised inside it
would become fmi2Fatal: :func:`deferred_interrupt` turns the first Ctrl-C or SIGTERM into a
flag that the run checks between steps, and :class:`RunTimeout` is what a run past its time
limit raises there.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator


class RunTimeout(Exception):
    """A run went past its time limit (raised between two communication steps)."""


#: Set by Ctrl-C or SIGTERM (to the signal's number) while :func:`deferred_interrupt` is
#: active.
_INTERRUPT: dict[str, int] = {"requested": 0}


class Terminated(KeyboardInterrupt):
    """SIGTERM stopped the command (handled as Ctrl-C is: what was computed is kept)."""

    def __init__(self) -> None:
        super().__init__("terminated (SIGTERM)")


def interruption(signum: int | None = None) -> KeyboardInterrupt:
    """The exception of a deferred Ctrl-C (KeyboardInterrupt) or SIGTERM (:class:`Terminated`)."""
    signum = _INTERRUPT["requested"] if signum is None else signum
    return Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def interrupt_requested() -> bool:
    """Whether a Ctrl-C or SIGTERM waits to be raised (see :func:`deferred_interrupt`)."""
    return bool(_INTERRUPT["requested"])


@contextlib.contextmanager
def deferred_interrupt() -> Iterator[None]:
    """Ctrl-C or SIGTERM raise between two communication steps, not inside an FMU.

    An FMU made with pythonfmu runs its Python code in this interpreter: a
    KeyboardInterrupt raised there becomes fmi2Fatal (the instance is lost and
    the run goes on with the next controller). Within this block the first
    Ctrl-C or SIGTERM only sets a flag, which the run looks at between two steps
    (:class:`papwc.master.observers.StepGuard`; ``papwc cosim`` after every row); a second
    one raises at once. SIGTERM raises :class:`Terminated`, a KeyboardInterrupt.
    Outside the main thread, or where Ctrl-C is ignored (battery workers),
    nothing changes; SIGTERM is deferred only where it has its default action.
    """
    if threading.current_thread() is not threading.main_thread() or (
            signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield
        return

    def handler(signum, frame) -> None:
        if _INTERRUPT["requested"]:
            raise interruption(signum)
        _INTERRUPT["requested"] = signum

    _INTERRUPT["requested"] = 0
    term = signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
    signal.signal(signal.SIGINT, handler)
    if term:
        signal.signal(signal.SIGTERM, handler)
    try:
        yield
        if _INTERRUPT["requested"]:
            raise interruption()
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        if term:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
        _INTERRUPT["requested"] = 0

