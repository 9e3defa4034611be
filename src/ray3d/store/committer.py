"""When a live run's rows reach the store: what the live loop hands over waits in memory (``WaitingRows``:
never more than ``max_waiting`` rows, so a slow or unreachable database never holds up the stream) and a thread of
its own commits it every ``every_s`` (``Committer``), so a process killed outright loses at most the last one."""

from __future__ import annotations

import threading
from collections.abc import Callable

from ray3d.store.database import Database, connect, shown
from ray3d.store.rows import WAITING_TABLES, write_rows


class WaitingRows:
    """The rows handed over and not written yet (any thread adds them), with each input's progress: never more
    than ``max_waiting`` rows; beyond, new rows are counted as ``lost`` and said once (``report``, of the store
    ``shown``). ``written``: each table's rows written so far; ``first_at``/``last_at``: the Unix times of the
    run's first frame and of its newest row."""

    def __init__(self, max_waiting: int, shown: str, report: Callable[[str], None]):
        self.max_waiting, self.shown, self.report = max_waiting, shown, report
        self.written = dict.fromkeys(WAITING_TABLES, 0)
        self.lost = 0
        self.first_at: float | None = None
        self.last_at: float | None = None
        self._rows: dict[str, list] = {table: [] for table in WAITING_TABLES}
        self._progress: dict[str, tuple[int, float]] = {}  # input -> (its last frame recorded, its Unix time)
        self._in_view: dict[str, tuple] = {}  # person -> their latest row of ``in_view``: state, not counted
        self._lock = threading.Lock()

    def add(self, table: str, rows: list, at_most: float | None = None) -> None:
        """``rows`` of ``table`` to be written, the newest of them at Unix time ``at_most``."""
        if not rows:
            return
        with self._lock:
            if self.left() + len(rows) > self.max_waiting:
                self.lost += len(rows)
                if self.lost == len(rows):
                    self.report(f"store {self.shown}: {self.max_waiting} rows wait to be written; "
                                "rows beyond are lost until it takes them")
                return
            self._rows[table].extend(rows)
            if at_most is not None:
                self.last_at = max(self.last_at or at_most, at_most)

    def progressed(self, source: str, frame: int, at: float) -> None:
        """Input ``source`` recorded up to its ``frame``, at Unix time ``at``."""
        with self._lock:
            self._progress[source] = (int(frame), at)
            if self.first_at is None:
                self.first_at = at

    def placed(self, rows: list[tuple]) -> None:
        """Rows of ``in_view`` (person first): each person's latest replaces the one waiting (never more than one
        a person, so never beyond ``max_waiting``)."""
        with self._lock:
            self._in_view.update((row[0], row) for row in rows)

    def taken(self) -> tuple[dict, dict, float | None]:
        """A copy of what waits, for the committer: (each table's rows, ``in_view`` too, each input's progress,
        ``last_at``)."""
        with self._lock:
            rows = {table: list(rows) for table, rows in self._rows.items()}
            return {**rows, "in_view": list(self._in_view.values())}, dict(self._progress), self.last_at

    def written_out(self, rows: dict, progress: dict) -> None:
        """What ``taken`` gave, committed: let go and counted (rows and progress added since are kept)."""
        with self._lock:
            for table, written in rows.items():
                if table == "in_view":  # let go where no newer row came since
                    for row in written:
                        if self._in_view.get(row[0]) == row:
                            del self._in_view[row[0]]
                    continue
                del self._rows[table][:len(written)]
                self.written[table] += len(written)
            for source, value in progress.items():
                if self._progress.get(source) == value:
                    del self._progress[source]

    def left(self) -> int:
        """How many rows wait."""
        return sum(len(rows) for rows in self._rows.values())


class Committer:
    """Run ``run``'s rows that wait (``waiting``) committed to the store at ``location`` by a thread of its own every
    ``every_s``, beginning on ``database`` (the connection the run began on); while the database is unreachable or
    refuses, the rows wait for the next try (said once, with ``report``), on a new connection."""

    def __init__(self, location, database: Database, waiting: WaitingRows, run: int, origin: float, every_s: float,
                 report: Callable[[str], None]):
        self.location, self.shown, self.report = location, shown(location), report
        self.waiting, self.run, self.origin, self.every_s = waiting, run, origin, every_s
        self._database: Database | None = database
        self._failed = False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._commit_every, name="store", daemon=True)
        self._thread.start()

    def _commit_every(self) -> None:
        while not self._stop.wait(self.every_s):
            self.commit()

    def commit(self) -> bool:
        """Write what waits in one transaction; whether it was written (if not, it waits for the next)."""
        rows, progress, last_at = self.waiting.taken()
        if not any(rows.values()) and not progress:
            return True
        try:
            write_rows(self.connected(), self.run, self.origin, self.waiting.first_at, rows, progress, last_at)
        except Exception as err:  # the database unreachable or refusing: kept, tried again
            if not self._failed:
                self._failed = True
                self.report(f"store {self.shown}: cannot write ({type(err).__name__}: "
                            f"{str(err).strip().splitlines()[0] if str(err).strip() else ''}); trying again")
            self.disconnect()
            return False
        self._failed = False
        self.waiting.written_out(rows, progress)
        return True

    @property
    def stopped(self) -> bool:
        return self._stop.is_set()

    def stop(self) -> None:
        """The thread stopped (a commit under way finished first); ``commit`` may still be called."""
        self._stop.set()
        self._thread.join()

    def connected(self) -> Database:
        """The connection to the store, made again where it was lost."""
        if self._database is None:
            self._database = connect(self.location)
        return self._database

    def disconnect(self) -> None:
        if self._database is not None:
            self._database.close()
            self._database = None
