"""The journal: finished runs, one JSON line each, fsync'ed as they finish, read back on resume.

The first line is a header: the journal format, the *key* of what determines a
run's results (the plant FMU's model identity -- its GUID, a digest of its
sources --, papwc's version and a digest of the code that runs in a worker)
and a fingerprint of the key and of every planned run. Each run record carries
the key too. ``--resume`` keeps a record only if it is well formed, belongs to
a planned run with the same parameters (``run_hash``) and has the current key;
every other line (a torn last line, a line that is not JSON, a record of the
wrong shape, a record of a run that timed out or whose worker died) is skipped
with a warning and its run computed again. A rebuilt FMU from the same sources
has the same GUID, so its finished runs are kept.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import signal
import threading
from collections.abc import Iterator, Mapping
from pathlib import Path

from papwc.errors import BatteryError, OutputError
from papwc.output_files import create_new, lock_folder, os_error_text
from papwc.results.pulses import ROW_COLUMNS

# --- journal ---------------------------------------------------------------------------------


#: File name of the journal in the output folder.
JOURNAL_NAME = "journal.jsonl"
#: Version of the journal's record layout (3: pulse rows with the table's quantum, no
#: smallest_m; the header's seed_offset).
JOURNAL_FORMAT = 3
#: Numbers every row of a controller's ``pulses`` holds (papwc run's pulses.csv columns).
_PULSE_KEYS = ("iteration", *ROW_COLUMNS)
#: Warnings about skipped lines kept per journal (the rest are counted).
_WARNINGS_KEPT = 20

_METRIC_TYPES = {"final_error_m": "number", "pulses": "int", "settle_time_s": "number",
                 "limit_cycle": "bool", "cycle_p2p_m": "number", "b_hat": "number",
                 "f_c_hat": "number"}
#: Metrics a record may lack (older records), checked where present.
_OPTIONAL_METRIC_TYPES = {"outcome": "str", "outcome_reason": "str", "pulse_ratio": "number",
                          "ends_farther": "bool", "settled_span_m": "number"}


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def record_problem(obj) -> str | None:
    """What is wrong with a run record's shape, or None if it can be used."""
    if not isinstance(obj, dict):
        return "not a JSON object"
    for name in ("battery", "run_id", "run_hash", "message"):
        if not isinstance(obj.get(name), str):
            return f"field {name!r} is missing or not a string"
    if obj.get("status") not in ("ok", "error"):
        return "field 'status' is not 'ok' or 'error'"
    controllers = obj.get("controllers")
    if not isinstance(controllers, list):
        return "field 'controllers' is not a list"
    if obj["status"] == "ok" and not controllers:
        return "status ok without controllers"
    for c in controllers:
        if not isinstance(c, dict):
            return "a controller is not an object"
        if not (isinstance(c.get("label"), str) and isinstance(c.get("kind"), str)
                and isinstance(c.get("error"), str) and _is_number(c.get("tolerance"))
                and isinstance(c.get("iterations"), list)):
            return "a controller lacks label, kind, tolerance, error or iterations"
        if "warning" in c and not isinstance(c["warning"], str):
            return "a controller's warning is not a string"
        if "pulses" in c and not (isinstance(c["pulses"], list) and all(
                isinstance(p, dict) and all(_is_number(p.get(k)) for k in _PULSE_KEYS)
                for p in c["pulses"])):
            return "a controller's pulses are not a list of pulse rows"
        for it in c["iterations"]:
            if not isinstance(it, dict) or not isinstance(it.get("error"), str) or not (
                    isinstance(it.get("iteration"), int)
                    and not isinstance(it.get("iteration"), bool)):
                return "an iteration lacks its number or error"
            checks = [*_METRIC_TYPES.items(),
                      *((n, k) for n, k in _OPTIONAL_METRIC_TYPES.items() if n in it)]
            for name, kind in checks:
                value = it.get(name)
                ok = (isinstance(value, bool) if kind == "bool"
                      else isinstance(value, str) if kind == "str"
                      else isinstance(value, int) and not isinstance(value, bool)
                      if kind == "int" else _is_number(value))
                if not ok:
                    return f"an iteration's {name!r} is missing or of the wrong type"
            if not it["error"] and not math.isfinite(it["final_error_m"]):
                return "an iteration without error has no finite final error"
    return None


def read_journal(path: Path, warnings: list[str] | None = None, strict: bool = False
                 ) -> tuple[dict | None, list[dict], int]:
    """Header, run records and the size in bytes of the complete lines of a journal.

    A line that cannot be used -- not JSON, torn (the writer was killed), not
    an object, with ``strict`` a run record of the wrong shape
    (:func:`record_problem`) -- is skipped; ``warnings`` (if given) gets one
    text per skipped line (a torn last line is not counted).
    """
    header, records, good = None, [], 0
    with open(path, "rb") as f:
        lines = f.read().split(b"\n")
    offset = 0
    skipped = 0

    def skip(i: int, why: str) -> None:
        nonlocal skipped
        skipped += 1
        if warnings is not None and skipped <= _WARNINGS_KEPT:
            warnings.append(f"{path}: line 1 (the header) is unreadable ({why})" if i == 0
                            else f"{path}: line {i + 1} skipped ({why}); its run is computed "
                            "again")

    for i, line in enumerate(lines):
        end = offset + len(line) + 1
        offset = end
        if not line.strip():
            continue
        last = i == len(lines) - 1
        try:
            obj = json.loads(line)
        except (ValueError, UnicodeDecodeError):
            if not last:
                skip(i, "not JSON")
            continue
        if last:
            # No newline after it: the writer was killed while writing it.
            continue
        if not isinstance(obj, dict):
            skip(i, "not a JSON object")
            continue
        if obj.get("type") == "header" and i == 0:
            header = obj
        elif obj.get("type") == "run":
            why = record_problem(obj) if strict else None
            if why is not None:
                skip(i, f"malformed record: {why}")
                continue
            records.append(obj)
        else:
            skip(i, "neither a header nor a run record")
            continue
        good = end
    if warnings is not None and skipped > _WARNINGS_KEPT:
        warnings.append(f"{path}: {skipped - _WARNINGS_KEPT} more lines skipped")
    return header, records, good


@contextlib.contextmanager
def _ctrl_c_held() -> Iterator[None]:
    """Hold Ctrl-C back for the block; one that arrives meanwhile is raised after it.

    In the main thread the SIGINT handler is replaced for the block by one that
    only notes the request: a Ctrl-C whose signal came just before the block
    (its Python handler not yet run) is then noted too, instead of raising
    KeyboardInterrupt inside the block. Elsewhere SIGINT is blocked in the
    thread (the main thread takes it).
    """
    if threading.current_thread() is not threading.main_thread():
        mask = getattr(signal, "pthread_sigmask", None)
        if mask is None:
            yield
            return
        blocked = mask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            yield
        finally:
            mask(signal.SIG_SETMASK, blocked)
        return
    held: list[int] = []
    old = signal.signal(signal.SIGINT, lambda signum, frame: held.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)
    if held:
        if callable(old):
            old(signal.SIGINT, None)
        elif old != signal.SIG_IGN:
            raise KeyboardInterrupt


def _os_error(path: Path, operation: str, exc: OSError) -> OutputError:
    return OutputError(f"cannot {operation} {str(path)!r}: {os_error_text(exc)}")


class Journal:
    """Append-only JSON-lines file of finished runs, fsync'ed per record and locked.

    Parameters
    ----------
    path : Path
        The journal file.
    header : dict
        Its header: ``format``, ``key``, ``fingerprint`` and descriptive fields.
    resume : bool
        Keep the usable records of an existing journal with the same fingerprint.
    overwrite : bool
        Start afresh even if the file holds records.
    planned : mapping, optional
        ``(battery, run_id) -> run_hash`` of the runs planned now; records of
        other runs, or of other parameters, are not kept.
    """

    def __init__(self, path: Path, header: dict, resume: bool, overwrite: bool,
                 planned: Mapping[tuple[str, str], str] | None = None) -> None:
        self.path = path
        self.records: dict[tuple[str, str], dict] = {}
        #: What was skipped when the journal was read back (one line each).
        self.warnings: list[str] = []
        self._planned = planned
        self._key = header.get("key")
        from papwc.output_files import make_folder

        make_folder(path.parent)
        if path.exists() and not path.is_file():
            raise OutputError(f"cannot write the journal {str(path)!r}: a folder is in the "
                              "way")
        # held until close(); another command writing into the folder is refused
        self._lock = lock_folder(path.parent, "papwc battery")
        try:
            self._open(header, resume, overwrite)
        except BaseException:
            self._lock.close()
            raise

    def _read(self) -> tuple[dict | None, list[dict]]:
        try:
            header, records, _ = read_journal(self.path, self.warnings, strict=True)
        except OSError as exc:
            raise _os_error(self.path, "read the journal", exc) from exc
        return header, records

    def _open(self, header: dict, resume: bool, overwrite: bool) -> None:
        path = self.path
        kept: list[dict] = []
        if path.exists() and resume:
            old, records = self._read()
            if old is not None:
                if old.get("format") != JOURNAL_FORMAT:
                    raise BatteryError(
                        f"{path}: cannot resume: the journal was written by another papwc "
                        f"(journal format {old.get('format')!r}, this one writes "
                        f"{JOURNAL_FORMAT}); use another --out, or --overwrite to start again")
                if old.get("seed_offset", 0) != header.get("seed_offset", 0):
                    raise BatteryError(
                        f"{path}: cannot resume: the journal's runs were drawn with "
                        f"--seed-offset {old.get('seed_offset', 0)}, these with "
                        f"{header.get('seed_offset', 0)}; resume with the journal's offset, "
                        "use another --out, or --overwrite to start again")
                if old.get("fingerprint") != header["fingerprint"]:
                    why = ("the plant FMU's model (its GUID) or papwc's code differs"
                           if old.get("key") != header.get("key")
                           else "the battery files resolve to other runs")
                    raise BatteryError(
                        f"{path}: cannot resume: {why} than when it was started; use another "
                        "--out, or --overwrite to start again")
            elif records:
                self.warnings.append(f"{path}: the header line is unreadable; the records "
                                     "that carry this battery's key are kept")
            kept = [r for r in records if self._usable(r)]
        elif path.exists() and not overwrite:
            _, records = self._read()
            if records:
                raise BatteryError(f"{path.parent} already holds a battery journal "
                                   f"({len(records)} runs); pass --resume to continue it or "
                                   "--overwrite to start again")
        self.records = {(r["battery"], r["run_id"]): r for r in kept}
        # Write the header and the records kept (compacted) into a new file.
        tmp = path.with_name(path.name + ".tmp")
        fd = create_new(tmp)  # never through a link planted there
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(json.dumps(header) + "\n")
                for record in self.records.values():
                    f.write(json.dumps(record) + "\n")
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, path)
            self._file = open(path, "a", encoding="utf-8")
        except OSError as exc:
            raise _os_error(path, "write the journal", exc) from exc

    def _usable(self, record: dict) -> bool:
        """Whether a well-formed record can stand for its run now (else it is recomputed)."""
        where = f"{self.path}: run {record['battery']} {record['run_id']}"
        if record.get("key") != self._key:
            self.warnings.append(f"{where}: computed with another FMU model or papwc code; "
                                 "computed again")
            return False
        if self._planned is not None:
            want = self._planned.get((record["battery"], record["run_id"]))
            if want is None:
                self.warnings.append(f"{where}: not a run of these batteries; dropped")
                return False
            if want != record["run_hash"]:
                self.warnings.append(f"{where}: its parameters differ; computed again")
                return False
        if record.get("transient"):
            self.warnings.append(f"{where}: had {record['message'][:80]!r}; computed again")
            return False
        return True

    def append(self, record: dict) -> None:
        """Persist one record (flush and fsync) and keep it.

        Ctrl-C is held back while the record is written, so that it is never
        half written nor written but not counted.
        """
        line = json.dumps(record) + "\n"
        with _ctrl_c_held():
            try:
                self._file.write(line)
                self._file.flush()
                os.fsync(self._file.fileno())
            except OSError as exc:
                raise _os_error(self.path, "append to the journal", exc) from exc
            self.records[(record["battery"], record["run_id"])] = record

    def close(self, release: bool = True) -> None:
        """Close the file; release the folder's lock unless ``release`` is false."""
        self._file.close()
        if release:
            self.release()

    def release(self) -> None:
        """Release the folder's lock (idempotent)."""
        self._lock.close()
