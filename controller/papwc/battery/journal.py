"""The journal: finished runs, one JSON line each, fsync'ed as they finish, read back on resume."""

from __future__ import annotations

import fcntl
import json
import os
from pathlib import Path

from papwc.errors import BatteryError

# --- journal ---------------------------------------------------------------------------------


#: File name of the journal in the output folder.
JOURNAL_NAME = "journal.jsonl"
#: Version of the journal's record layout.
JOURNAL_FORMAT = 1


def read_journal(path: Path) -> tuple[dict | None, list[dict], int]:
    """Header, run records and the size in bytes of the complete lines of a journal.

    A last line that is not complete JSON (the writer was killed) is ignored;
    a bad line before the last one raises :class:`BatteryError`.
    """
    header, records, good = None, [], 0
    with open(path, "rb") as f:
        lines = f.read().split(b"\n")
    offset = 0
    for i, line in enumerate(lines):
        end = offset + len(line) + 1
        is_last = i == len(lines) - 1 or (i == len(lines) - 2 and lines[-1] == b"")
        if not line:
            offset = end
            continue
        try:
            obj = json.loads(line)
            if not isinstance(obj, dict) or i == len(lines) - 1:
                raise ValueError("incomplete line")
        except ValueError as exc:
            if is_last:
                break
            raise BatteryError(f"{path}: line {i + 1} is not a journal record") from exc
        if obj.get("type") == "header":
            header = obj
        elif obj.get("type") == "run":
            records.append(obj)
        offset = good = end
    return header, records, good


class Journal:
    """Append-only JSON-lines file of finished runs, fsync'ed per record and locked."""

    def __init__(self, path: Path, header: dict, resume: bool, overwrite: bool) -> None:
        self.path = path
        self.records: dict[tuple[str, str], dict] = {}
        path.parent.mkdir(parents=True, exist_ok=True)
        lock_path = path.with_name(path.name + ".lock")
        self._lock = open(lock_path, "a")  # held until close()
        try:
            fcntl.flock(self._lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            self._lock.close()
            raise BatteryError(f"{path.parent}: another battery is writing into this "
                               "folder") from None
        try:
            self._open(header, resume, overwrite)
        except BaseException:
            self._lock.close()
            raise

    def _open(self, header: dict, resume: bool, overwrite: bool) -> None:
        path = self.path
        if path.exists() and resume:
            old, records, good = read_journal(path)
            if old is not None and old.get("fingerprint") != header["fingerprint"]:
                why = ("the plant FMU differs" if old.get("fmu_sha256") != header["fmu_sha256"]
                       else "the battery files resolve to other runs")
                raise BatteryError(f"{path}: cannot resume: {why} than when it was started; "
                                   "use another --out, or --overwrite to start again")
            if old is not None:
                with open(path, "r+b") as f:
                    f.truncate(good)
                    f.flush()
                    os.fsync(f.fileno())
                self.records = {(r["battery"], r["run_id"]): r for r in records}
                self._file = open(path, "a", encoding="utf-8")
                return
        elif path.exists() and not overwrite and read_journal(path)[1]:
            _, records, _ = read_journal(path)
            raise BatteryError(f"{path.parent} already holds a battery journal "
                               f"({len(records)} runs); pass --resume to continue it or "
                               "--overwrite to start again")
        tmp = path.with_name(path.name + ".tmp")
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(json.dumps(header) + "\n")
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
        self._file = open(path, "a", encoding="utf-8")

    def append(self, record: dict) -> None:
        """Persist one record (flush and fsync) and keep it."""
        self._file.write(json.dumps(record) + "\n")
        self._file.flush()
        os.fsync(self._file.fileno())
        self.records[(record["battery"], record["run_id"])] = record

    def close(self) -> None:
        """Close the file and release the lock."""
        self._file.close()
        self._lock.close()
