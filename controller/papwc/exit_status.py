"""A command's body run to an exit status, each failure said in one line on standard error.

Used by the ``papwc`` command line (:mod:`papwc.cli`) and by the modules run as ``python -m``
(the studies beside the package, ``python -m papwc_studies.NAME``).
"""

from __future__ import annotations

import sys
from collections.abc import Callable

from papwc.errors import PapwcError

#: The flags the out-of-memory message names when a command names none of its own.
MEMORY_HINT = "--max-steps, --max-runs, --workers"


def run_command(name: str, run: Callable[[], int | None], memory_hint: str | None = None
                ) -> int:
    """Run a command's body ``run``; return its exit code, its failures each in one line.

    ``name`` opens the line on standard error (``papwc run``, ``python -m
    papwc_studies.ringing``). Exit codes as :func:`main`'s: a :class:`PapwcError` its own
    (2 by default), Ctrl-C 130, an operating-system error (also standard output closed or
    full) or no memory 1 (the message names ``memory_hint``, the flags that lower the work).
    ``SystemExit`` (argparse's refusals) passes through.
    """
    stdout = sys.stdout
    # Standard output closed when the process started (``>&-``): Python sets sys.stdout to
    # None and print() then writes nothing, silently; writing it fails here instead.
    sys.stdout = _Stdout(stdout if stdout is not None else _Closed())
    try:
        code = int(run() or 0)
        sys.stdout.flush()
        return code
    except PapwcError as exc:
        _error(name, str(exc))
        return getattr(exc, "exit_code", 2)
    except KeyboardInterrupt as exc:
        if str(exc) == "terminated (SIGTERM)":  # papwc.interrupts.Terminated
            _error(name, "terminated (SIGTERM)", prefix="")
            return 143
        _error(name, "interrupted", prefix="")
        return 130
    except OSError as exc:
        if _is_stdout_error(exc):
            _silence_stdout(stdout)
            _error(name, f"cannot write to standard output: {exc.strerror or exc}")
        else:
            _error(name, describe_os_error(exc))
        return 1
    except MemoryError:
        _error(name, "out of memory; lower the work asked for (e.g. "
                     f"{memory_hint or MEMORY_HINT})")
        return 1
    finally:
        if isinstance(sys.stdout, _Stdout):
            sys.stdout = stdout


class _StdoutError(OSError):
    """Writing standard output failed (a closed pipe, a full device)."""


class _Closed:
    """Standard output that was closed before the process started: every write fails."""

    def write(self, text: str) -> int:
        import errno

        raise OSError(errno.EBADF, "it is closed (the command was started with >&-)")

    def flush(self) -> None:
        """Nothing is held."""

    def fileno(self) -> int:
        raise ValueError("standard output is closed")


class _Stdout:
    """Standard output whose write errors are told apart from other OSErrors."""

    def __init__(self, stream) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except OSError as exc:
            raise _StdoutError(exc.errno, exc.strerror) from exc

    def flush(self) -> None:
        try:
            self._stream.flush()
        except OSError as exc:
            raise _StdoutError(exc.errno, exc.strerror) from exc

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


def _error(name: str, text: str, prefix: str = "error: ") -> None:
    if sys.stderr is not None:
        try:
            print(f"{name}: {prefix}{text}", file=sys.stderr)
        except OSError:
            pass


def _is_stdout_error(exc: OSError) -> bool:
    """Whether ``exc`` came from writing standard output (closed pipe, full device)."""
    return isinstance(exc, _StdoutError)


def _silence_stdout(stream) -> None:
    """Point the file of ``stream`` to the null device, so that nothing fails at exit."""
    import os

    try:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, stream.fileno())
        os.close(null)
    except (OSError, AttributeError, ValueError):
        pass


def describe_os_error(exc: OSError) -> str:
    """An operating-system error in one line: the operation, the path(s), the reason."""
    import traceback

    frames = traceback.extract_tb(exc.__traceback__)
    operation = frames[-1].name if frames else "operation"
    reason = exc.strerror or str(exc) or type(exc).__name__
    if exc.filename is None:
        return f"{operation}: {reason}"
    paths = repr(str(exc.filename))
    if exc.filename2 is not None:
        paths += f" -> {str(exc.filename2)!r}"
    return f"{operation} {paths}: {reason}"
