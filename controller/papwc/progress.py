"""What a long command is doing while it works: ``papwc build``, ``papwc identify``.

A command opens a :class:`Progress`; code deep inside it says what starts with
:func:`doing` (a no-op when no command listens, e.g. in a library call or a test). On a
terminal (standard error a TTY) the current step is one status line, rewritten every
:data:`TERMINAL_REFRESH_S` seconds with the time it has taken; otherwise (a log, a pipe,
CI) each step is one line when it starts and another every :data:`PLAIN_PROGRESS_S`
seconds while it lasts, so that a long step is never mistaken for a hang. The battery's
progress bar keeps the same rhythm off a terminal (:mod:`papwc.battery.orchestrate`).
"""

from __future__ import annotations

import sys
import threading
import time
from typing import TextIO

__all__ = ["PLAIN_PROGRESS_S", "TERMINAL_REFRESH_S", "Progress", "doing", "note_once", "say"]

#: Seconds between two progress lines when standard error is not a terminal.
PLAIN_PROGRESS_S = 10.0
#: Seconds between two refreshes of the status line on a terminal.
TERMINAL_REFRESH_S = 1.0

#: The Progress of the command running in this process (innermost last).
_ACTIVE: list[Progress] = []
#: Notes said once per process (:func:`note_once`).
_NOTED: set[str] = set()


class Progress:
    """The progress of one command on ``stream`` (default: standard error).

    Parameters
    ----------
    name : str
        Opens every line (``"papwc build"``).
    stream : text stream, optional
        Where the lines go (default ``sys.stderr``).
    tty : bool, optional
        Whether ``stream`` is a terminal (default: ``stream.isatty()``).

    Used as a context manager; :meth:`doing` starts a step, :meth:`say` writes a line.
    Writing never raises (a closed stream only silences it).
    """

    def __init__(self, name: str, stream: TextIO | None = None, tty: bool | None = None) -> None:
        self.name = name
        self.stream = stream if stream is not None else sys.stderr
        if tty is None:
            try:
                tty = bool(self.stream.isatty())
            except (AttributeError, OSError, ValueError):
                tty = False
        self.tty = tty
        self._what = ""
        self._since = time.monotonic()
        self._told = self._since
        self._shown = False  # a status line is on the terminal
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def __enter__(self) -> Progress:
        _ACTIVE.append(self)
        self._thread = threading.Thread(target=self._beat, name="papwc-progress", daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        with self._lock:
            self._clear()
        if self in _ACTIVE:
            _ACTIVE.remove(self)

    def doing(self, what: str) -> None:
        """A step starts: ``what`` it does (one line off a terminal, the status line on one)."""
        with self._lock:
            self._what, self._since = what, time.monotonic()
            self._told = self._since
            if self.tty:
                self._status()
            else:
                self._write(f"{self.name}: {what}\n")

    def say(self, text: str) -> None:
        """One line that stays (a result), above the status line on a terminal."""
        with self._lock:
            self._clear()
            self._write(f"{self.name}: {text}\n")
            if self.tty and self._what:
                self._status()

    def done(self) -> None:
        """The current step has ended (nothing more is said of it)."""
        with self._lock:
            self._what = ""
            self._clear()

    # -- inside ------------------------------------------------------------------------------
    def _beat(self) -> None:
        interval = TERMINAL_REFRESH_S if self.tty else min(PLAIN_PROGRESS_S, 1.0)
        while not self._stop.wait(interval):
            with self._lock:
                if not self._what:
                    continue
                now = time.monotonic()
                if self.tty:
                    self._status()
                elif now - self._told >= PLAIN_PROGRESS_S:
                    self._told = now
                    self._write(f"{self.name}: {self._what} ({now - self._since:.0f} s so "
                                "far)\n")

    def _status(self) -> None:
        seconds = time.monotonic() - self._since
        self._write(f"\r\x1b[K{self.name}: {self._what} ({seconds:.0f} s)")
        self._shown = True

    def _clear(self) -> None:
        if self._shown:
            self._write("\r\x1b[K")
            self._shown = False

    def _write(self, text: str) -> None:
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError, AttributeError):
            pass


def doing(what: str) -> None:
    """Tell the running command's :class:`Progress` that ``what`` starts (else nothing)."""
    if _ACTIVE:
        _ACTIVE[-1].doing(what)


def say(text: str) -> None:
    """A line of the running command's :class:`Progress` (else nothing)."""
    if _ACTIVE:
        _ACTIVE[-1].say(text)


def note_once(key: str, text: str) -> None:
    """:func:`say` ``text`` the first time ``key`` is noted in this process."""
    if _ACTIVE and key not in _NOTED:
        _NOTED.add(key)
        say(text)
