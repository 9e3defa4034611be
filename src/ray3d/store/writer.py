"""A run's record written as it happens (``RunRecorder``): what the live loop hands over is made into rows
(``rows``), kept in memory and committed by a thread of its own every ``commit_every_s`` (half a second), so a
process killed outright loses at most the last one, and a slow or unreachable database never holds up the stream
(at most ``max_waiting`` rows wait; beyond, new rows are counted as lost and said once: ``committer``).

Beginning (``begin_run``), it takes the store's writer lock (``lock.WriterLock``: one live run writes a store at a
time), closes what runs cut off left open (``restart.take_over_cut_off_runs``: ``closed``, or ``carried``: the
people in view then, whom this run may take up with their ids, kept in the store until their tracks end), reads the
counts so far (``counted``), numbers the run, notes where each input was last recorded (closed as a gap, "the
service was down", at the input's first frame of this run) and says where each file input is to be taken up again
(``Resume``): the frame after the last one recorded, on the clock of the run that began it. What each camera's
people show of the floor is written the same way (``floor``), and read back for the next run
(``remembered_floor``)."""

from __future__ import annotations

import dataclasses
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path

from ray3d.site.events import CarriedPerson
from ray3d.store.committer import Committer, WaitingRows
from ray3d.store.database import Database, connect, shown, without_passwords
from ray3d.store.lock import WriterLock, lock_path
from ray3d.store.reader import remembered_floor
from ray3d.store.restart import counts_so_far, take_over_cut_off_runs
from ray3d.store.rows import OncePerSecond, event_rows, floor_rows, in_view_rows

DOWN_BETWEEN_RUNS = "the service was down"


@dataclasses.dataclass(frozen=True)
class Resume:
    """Where input ``source`` is taken up: its first frame, and the Unix time of its frame 0 (``origin``)."""

    source: str
    first_index: int
    origin: float


@dataclasses.dataclass(frozen=True)
class Beginning:
    """What a run found and took as it began on a store (``begin_run``): its number (``run``), where each input is
    taken up (``resumes``), when each input the store knows was last recorded (``down_since``, Unix time: the gap
    since is closed at its first frame of this run), what runs cut off left open (``closed``, ``carried``:
    ``restart.take_over_cut_off_runs``) and the counts so far (``counted``)."""

    run: int
    resumes: list[Resume]
    down_since: dict[str, float]
    closed: list[dict]
    carried: list[CarriedPerson]
    counted: dict


def begin_run(database: Database, command: str, sources: list[str], files: list[bool], site: dict | None,
              origin: float | None) -> Beginning:
    """A run of ``command`` on ``sources`` (``files``: whether each is a file) begun on the store, by its one
    writer: numbered, each input taken up (a file: after its last recorded frame, on the clock it was begun on;
    else at frame 0 on ``origin``, or now) and what runs cut off left open taken over."""
    now = time.time()
    previous = {source: (frame, at, first) for source, frame, at, first in database.rows(
        "SELECT source, frame, at, origin FROM progress")}
    taken_up = [previous[s] for s, is_file in zip(sources, files) if is_file and s in previous]
    # One file taken up where it was left: its stream clock goes on, and so may the people in view then.
    closed, carried = take_over_cut_off_runs(database, carry=len(sources) == 1 == len(taken_up))
    counted = counts_so_far(database)
    clock = taken_up[0][2] if taken_up else origin if origin is not None else now
    resumes = [Resume(s, previous[s][0] + 1 if is_file and s in previous else 0, clock)
               for s, is_file in zip(sources, files)]
    run = database.rows("INSERT INTO runs (started_at, command, sources, site) VALUES (?, ?, ?, ?) RETURNING run",
                        (now, without_passwords(command), json.dumps(sources),
                         json.dumps(site) if site else None))[0][0]
    database.commit()
    return Beginning(int(run), resumes, {s: previous[s][1] for s in sources if s in previous}, closed, carried,
                     counted)


class RunRecorder:
    """One run's writer on the store at ``location``, refused (``InputError`` naming it) while another process
    writes it. ``run``: its number (person ids of this run carry it); ``closed``: the events that closed what runs
    cut off left open (already in the store); ``counted``: each zone's entries and exits and each line's crossings
    before this run, in the form of ``SiteMonitor.counts``. The rows handed over wait
    (``committer.WaitingRows``) for a thread of its own to commit them (``committer.Committer``)."""

    def __init__(self, location, command: str, sources: list[str], files: list[bool], site: dict | None = None,
                 origin: float | None = None, commit_every_s: float = 0.5, max_waiting: int = 200_000,
                 report: Callable[[str], None] = lambda line: print(line, file=sys.stderr)):
        # A stream's URL is recorded without its password (the store is read by whoever reports on the site).
        self.location, self.sources, self.report = location, [without_passwords(s) for s in sources], report
        self.shown = shown(location)  # as said in messages (a PostgreSQL URL without its password)
        self._writer = WriterLock(location)
        self._writer.take()
        database = None
        try:
            database = connect(location)
            self._writer.note_holder(database)
            begun = begin_run(database, command, self.sources, files, site, origin)
        except BaseException:
            if database is not None:
                database.close()
            self._writer.release()
            raise
        self.run, self.resumes, self.closed, self.carried, self.counted = \
            begun.run, begun.resumes, begun.closed, begun.carried, begun.counted
        self._down_since = dict(begun.down_since)
        # Whether the store already held a record of these inputs (this run appends to what they wrote).
        self.continues = bool(self._down_since)
        self.origin = self.resumes[0].origin  # every input's frame 0, one clock
        self._waiting = WaitingRows(max_waiting, self.shown, report)
        self.written = self._waiting.written  # each table's rows written so far
        self._seq = 0
        self._once_a_second = OncePerSecond()
        self._committer = Committer(location, database, self._waiting, self.run, self.origin, commit_every_s, report)

    @property
    def id_prefix(self) -> str:
        """Before each person's id in this run: ids are unique across the runs of a store."""
        return f"{self.run}-"

    @property
    def lost(self) -> int:
        """Rows handed over while ``max_waiting`` rows waited: never written."""
        return self._waiting.lost

    # What the live loop hands over (any thread).

    def events(self, events: list[dict]) -> None:
        rows, ended = event_rows(self.run, self._seq, self.origin, events)
        self._seq += len(rows)
        self._waiting.add("events", rows, at_most=max((r[2] for r in rows), default=None))
        self._waiting.add("ended", ended)

    def positions(self, time_s: float, people, camera: str) -> None:
        """The people of a settled frame (``PersonNow``), each kept once per whole second of stream time, and in
        view (``in_view_rows``) as the latest, for a run that takes them up after a cut."""
        second, rows, camera = int(time_s // 1.0), [], without_passwords(camera)
        self._waiting.placed(in_view_rows(self.run, self.origin + time_s, people))
        for person in people:
            if not self._once_a_second.keep(person.track, second):
                continue
            sd = [float(v) for v in person.position_sd] if person.position_sd is not None else [None, None]
            rows.append((self.run, person.track, self.origin + time_s, float(person.joints[0, 0]),
                         float(person.joints[0, 1]), sd[0], sd[1], camera))
        self._waiting.add("positions", rows, at_most=self.origin + time_s if rows else None)

    def left(self, people: list[str]) -> None:
        """``people`` gone from view (their tracks ended, announced or not): no longer in ``in_view``."""
        self._waiting.add("ended", [(person,) for person in people])

    def person(self, person: str, first_s: float, last_s: float, stature_m: float | None, stature_class: str,
               rejoins: int, camera: str) -> None:
        self._waiting.add("people", [(person, self.run, self.origin + first_s, self.origin + last_s, stature_m,
                                      stature_class, int(rejoins), without_passwords(camera))])

    def gap(self, camera: str, from_at: float, to_at: float, why: str) -> None:
        self._waiting.add("gaps", [(self.run, without_passwords(camera), float(from_at), float(to_at), why)])

    def behind(self, camera: str, from_s: float, to_s: float, share: float) -> None:
        """A stretch of stream time in which the run could not keep up with ``camera`` (``share`` of its frames
        dropped): its counts are uncertain."""
        self._waiting.add("behind", [(self.run, without_passwords(camera), self.origin + float(from_s),
                                      self.origin + float(to_s), float(share))])

    def floor(self, camera: str, centre, evidence, keypoints: str | None = None) -> None:
        """What a camera's people showed of the floor itself (``SizeEvidence`` and ``SeenTwice``), seen from its
        (3,) ``centre`` by a detector of ``keypoints`` (a layout)."""
        self._waiting.add("floor", floor_rows(self.run, without_passwords(camera), time.time(), centre, evidence,
                                              keypoints))

    def remembered_floor(self, cameras: list[tuple[str, object]]) -> tuple:
        """What earlier runs' people showed of these cameras' floor, each camera (its name, its (3,) centre)
        where it stands now (``reader.remembered_floor``); nothing where the store cannot be read."""
        try:
            return remembered_floor(self.location, [(without_passwords(name), centre) for name, centre in cameras])
        except Exception as err:  # the store unreachable now: the run starts on its own people
            self.report(f"store {self.shown}: what earlier runs showed of the floor could not be read "
                        f"({type(err).__name__})")
            return ()

    def progress(self, source: str, frame: int, time_s: float) -> None:
        """Input ``source`` recorded up to its ``frame``, at ``time_s`` of stream time. Its first frame of the run
        closes the gap since the last run."""
        source = without_passwords(source)
        if (down_since := self._down_since.pop(source, None)) is not None:
            self.gap(source, down_since, self.origin + time_s, DOWN_BETWEEN_RUNS)
        self._waiting.progressed(source, frame, self.origin + time_s)

    def commit(self) -> bool:
        """Write what waits in one transaction; whether it was written (if not, it waits for the next)."""
        return self._committer.commit()

    def discard(self) -> None:
        """A run that never started (its inputs could not be opened) taken out of the store; an SQLite store that
        holds nothing else is removed."""
        self._committer.stop()
        database = self._committer.connected()
        database.execute("DELETE FROM runs WHERE run = ?", (self.run,))
        others = database.rows("SELECT COUNT(*) FROM runs")[0][0]
        database.commit()
        self._committer.disconnect()
        self._writer.release()
        if not others and not database.postgresql:
            _remove_sqlite_store(self.location)

    def close(self, ending: str) -> None:
        """Every row waiting written (tried for a few seconds where the database is down), the run's end noted.
        Closing again does nothing."""
        if self._committer.stopped:
            return
        self._committer.stop()
        for source, down_since in self._down_since.items():  # an input that gave no frame this run
            self.gap(source, down_since, max(down_since, time.time()), DOWN_BETWEEN_RUNS)
        self._down_since.clear()
        deadline = time.monotonic() + 5.0
        while not self._committer.commit() and time.monotonic() < deadline:
            time.sleep(0.5)
        try:
            database = self._committer.connected()
            database.execute("UPDATE runs SET ended_at = ?, ending = ? WHERE run = ?", (time.time(), ending, self.run))
            database.commit()
        except Exception as err:
            self.report(f"store {self.shown}: the run's end could not be noted ({type(err).__name__})")
        finally:
            if left := self._waiting.left():
                self.report(f"store {self.shown}: {left} rows could not be written")
            self._committer.disconnect()
            self._writer.release()  # the next run may begin


def _remove_sqlite_store(location) -> None:
    """An SQLite store's files (its database, write-ahead log, shared memory and writer lock) removed."""
    for path in (*(Path(f"{location}{suffix}") for suffix in ("", "-wal", "-shm")), lock_path(location)):
        path.unlink(missing_ok=True)
