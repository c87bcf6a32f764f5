"""
The invocations that worked on a benchmark grid (a long grid often takes several), so that their time is not lost:
``invocations.json`` in each grid's log folder, written by :class:`InvocationJournal`, read by :func:`read_invocations`.
"""

from __future__ import annotations

import datetime
import json
import os
import threading
import time
import uuid
from collections.abc import Callable, Iterable, Sequence
from operator import methodcaller
from typing import Any

from sb3_adc.common.atomic import write_atomically

#: File of a grid's log folder that records the invocations that worked on it.
INVOCATIONS_JSON = "invocations.json"
#: Run outcomes an entry counts (``RunOutcome.status``).
STATUSES = ("trained", "resumed", "skipped", "failed")
#: Largest ``invocations.json`` read (a grid's file grows by a few hundred bytes per invocation).
MAX_FILE_BYTES = 1_000_000


class InvocationJournal:
    """
    A context manager writing one invocation's entry in ``invocations.json`` of each grid folder it works on (as it
    starts, as runs finish and on a heartbeat): ``id``, ``started`` (UTC), ``wall_time_s``, ``workers``, ``backend``,
    ``algos``, ``runs_in_grid``, ``runs`` (per status) and ``finished`` (stays ``False`` after Ctrl-C or a kill).

    :param grids: Each grid's log folder with its algorithms and its number of runs
    :param workers: Worker processes (or the Ray backend's ``"cluster"``)
    :param backend: ``local`` or ``ray``
    :param heartbeat_s: Seconds between two updates of the wall time while runs go on
    :param clock: Seconds of a monotonic clock (tests pass their own)
    """

    def __init__(
        self,
        grids: Sequence[tuple[str, Sequence[str], int]],
        workers: int | str,
        backend: str,
        heartbeat_s: float = 60.0,
        clock: Callable[[], float] = time.monotonic,
    ):
        self.folders = [folder for folder, _, _ in grids]
        self.heartbeat_s = heartbeat_s
        self.clock = clock
        self.id = uuid.uuid4().hex
        started = datetime.datetime.now(datetime.timezone.utc).isoformat()
        entry = {"id": self.id, "started": started, "wall_time_s": 0.0, "workers": workers, "backend": backend}
        self.entries: dict[str, dict[str, Any]] = {}
        for folder, algos, runs in grids:
            grid = {"algos": sorted(set(algos)), "runs_in_grid": runs, "runs": dict.fromkeys(STATUSES, 0)}
            self.entries[folder] = {**entry, **grid, "finished": False}
        self._start = clock()
        self._others: dict[str, list[dict[str, Any]]] = {}  # read once: the folder's lock keeps other writers out
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._heartbeat = threading.Thread(target=self._beat, name="invocation-journal", daemon=True)

    def __enter__(self) -> InvocationJournal:
        self._others = {folder: _read(os.path.join(folder, INVOCATIONS_JSON)) for folder in self.folders}
        self._write()
        self._heartbeat.start()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, *_: object) -> None:
        self._stop.set()
        self._heartbeat.join()
        with self._lock:
            for entry in self.entries.values():
                entry["finished"] = exc_type is None
        self._write()

    def record(self, folder: str, status: str) -> None:
        """
        Count a finished run of a grid folder.

        :param folder: The grid's log folder (as given)
        :param status: The run's outcome (:data:`STATUSES`)
        """
        with self._lock:
            self.entries[folder]["runs"][status] += 1
        self._write()

    def _beat(self) -> None:
        while not self._stop.wait(self.heartbeat_s):
            self._write()

    def _write(self) -> None:
        with self._lock:
            elapsed = round(self.clock() - self._start, 1)
            for folder, entry in self.entries.items():
                entry["wall_time_s"] = elapsed
                os.makedirs(folder, exist_ok=True)
                text = json.dumps([*self._others[folder], entry], indent=2) + "\n"
                write_atomically(os.path.join(folder, INVOCATIONS_JSON), methodcaller("write", text))


def read_invocations(folders: Iterable[str]) -> list[dict[str, Any]]:
    """
    The invocations recorded in grid folders, oldest first, each once: one that worked on several of the folders has
    its runs summed, its algorithms merged and its longest wall time.

    :param folders: The grids' log folders (those without ``invocations.json`` add nothing)
    """
    merged: dict[str, dict[str, Any]] = {}
    for folder in folders:
        for entry in _read(os.path.join(folder, INVOCATIONS_JSON)):
            known = merged.get(entry["id"])
            if known is None:
                merged[entry["id"]] = {**entry, "runs": dict(entry["runs"]), "algos": list(entry["algos"])}
                continue
            for status, count in entry["runs"].items():
                known["runs"][status] = known["runs"].get(status, 0) + count
            known["runs_in_grid"] += entry["runs_in_grid"]
            known["algos"] = sorted(set(known["algos"]) | set(entry["algos"]))
            known["wall_time_s"] = max(known["wall_time_s"], entry["wall_time_s"])
            known["finished"] = known["finished"] and entry["finished"]
    return sorted(merged.values(), key=lambda entry: entry["started"])


def _read(path: str) -> list[dict[str, Any]]:
    """The entries of an ``invocations.json`` (none if absent); an unreadable one is set aside as ``*.damaged``."""
    if not os.path.isfile(path):
        return []
    try:
        if os.path.getsize(path) > MAX_FILE_BYTES:
            raise ValueError(f"larger than {MAX_FILE_BYTES} bytes")
        with open(path, encoding="utf-8") as stream:
            entries = json.load(stream)
        if not isinstance(entries, list) or not all(isinstance(entry, dict) and "id" in entry for entry in entries):
            raise ValueError("not a list of invocation entries")
    except (OSError, ValueError) as error:
        os.replace(path, path + ".damaged")
        print(f"{path} is unreadable ({error}); set aside as {os.path.basename(path)}.damaged.")
        return []
    return entries
