"""A run's record written as it happens (``RunRecorder``): what the live loop hands over is kept in memory and
committed by a thread of its own every ``commit_every_s`` (half a second), so a process killed outright loses at
most the last one, and a slow or unreachable database never holds up the stream (at most ``max_waiting`` rows
wait; beyond, new rows are counted as lost and said once).

Beginning, it takes the store's writer lock (``lock.WriterLock``: one live run writes a store at a time), closes
what runs cut off left open (``restart.take_over_cut_off_runs``: ``closed``, or ``carried``: the people in view
then, whom this run may take up with their ids, kept in the store until their tracks end), reads the counts so far
(``counted``), numbers the run, notes where each input was last recorded (closed as a gap, "the service was
down", at the input's first frame of this run) and says where each file input is to be taken up again
(``Resume``): the frame after the last one recorded, on the clock of the run that began it. What each camera's
people show of the
floor is written the same way (``floor``), and read back for the next run (``remembered_floor``)."""

from __future__ import annotations

import dataclasses
import json
import sys
import threading
import time
from collections.abc import Callable

from ray3d.refine.ankle_plane import SeenTwice
from ray3d.site.events import TRACK_ENDED
from ray3d.store.database import Database, connect, shown, without_passwords
from ray3d.store.lock import WriterLock, lock_path
from ray3d.store.reader import remembered_floor
from ray3d.store.restart import counts_so_far, take_over_cut_off_runs

DOWN_BETWEEN_RUNS = "the service was down"


@dataclasses.dataclass(frozen=True)
class Resume:
    """Where input ``source`` is taken up: its first frame, and the Unix time of its frame 0 (``origin``)."""

    source: str
    first_index: int
    origin: float


class RunRecorder:
    """One run's writer on the store at ``location``, refused (``InputError`` naming it) while another process
    writes it. ``run``: its number (person ids of this run carry it); ``closed``: the events that closed what runs
    cut off left open (already in the store); ``counted``: each zone's entries and exits and each line's crossings
    before this run, in the form of ``SiteMonitor.counts``."""

    def __init__(self, location, command: str, sources: list[str], files: list[bool], site: dict | None = None,
                 origin: float | None = None, commit_every_s: float = 0.5, max_waiting: int = 200_000,
                 report: Callable[[str], None] = lambda line: print(line, file=sys.stderr)):
        # A stream's URL is recorded without its password (the store is read by whoever reports on the site).
        self.location, self.sources, self.report = location, [without_passwords(s) for s in sources], report
        self.shown = shown(location)  # as said in messages (a PostgreSQL URL without its password)
        self.commit_every_s, self.max_waiting = commit_every_s, max_waiting
        self._writer = WriterLock(location)
        self._writer.take()
        try:
            self._database: Database | None = connect(location)
            self.run, self.resumes, self._down_since = self._begin(command, files, site, origin)
        except BaseException:
            if getattr(self, "_database", None) is not None:
                self._database.close()
            self._writer.release()
            raise
        # Whether the store already held a record of these inputs (this run appends to what they wrote).
        self.continues = bool(self._down_since)
        self.origin = self.resumes[0].origin  # every input's frame 0, one clock
        self.written = {"events": 0, "positions": 0, "people": 0, "gaps": 0, "floor": 0, "behind": 0, "carried": 0}
        self.lost = 0
        self._seq = 0
        self._last_at: float | None = None
        self._first_at: float | None = None  # the run's first frame (Unix time)
        # person -> the last whole second of stream time a position was kept (of those seen in the last seconds)
        self._second: dict[str, int] = {}
        self._pruned_at: int | None = None
        self._waiting: dict[str, list] = {"events": [], "positions": [], "people": [], "gaps": [], "floor": [],
                                          "behind": [], "carried": []}  # carried: the carried whose tracks ended
        self._carrying = {person.person for person in self.carried}
        self._progress: dict[str, tuple[int, float]] = {}
        self._failed = False
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._committer = threading.Thread(target=self._commit_every, name="store", daemon=True)
        self._committer.start()

    def _begin(self, command: str, files: list[bool], site: dict | None, origin: float | None):
        """The run's number, where each input is taken up (a file: after its last recorded frame, on the clock
        it was begun on) and the gaps since the last run, each closed at this run's first frame of its input."""
        database, now = self._database, time.time()
        self._writer.note_holder(database)
        previous = {source: (frame, at, first) for source, frame, at, first in database.rows(
            "SELECT source, frame, at, origin FROM progress")}
        taken_up = [previous[s] for s, is_file in zip(self.sources, files) if is_file and s in previous]
        # One file taken up where it was left: its stream clock goes on, and so may the people in view then.
        self.closed, self.carried = take_over_cut_off_runs(database, carry=len(self.sources) == 1 == len(taken_up))
        self.counted = counts_so_far(database)
        clock = taken_up[0][2] if taken_up else origin if origin is not None else now
        resumes = [Resume(s, previous[s][0] + 1 if is_file and s in previous else 0, clock)
                   for s, is_file in zip(self.sources, files)]
        run = database.rows("INSERT INTO runs (started_at, command, sources, site) VALUES (?, ?, ?, ?) RETURNING run",
                            (now, without_passwords(command), json.dumps(self.sources),
                             json.dumps(site) if site else None))[0][0]
        database.commit()
        return int(run), resumes, {s: previous[s][1] for s in self.sources if s in previous}

    @property
    def id_prefix(self) -> str:
        """Before each person's id in this run: ids are unique across the runs of a store."""
        return f"{self.run}-"

    # What the live loop hands over (any thread).

    def events(self, events: list[dict]) -> None:
        rows, ended = [], []
        for event in events:
            if event["event"] == TRACK_ENDED.name and event["track"] in self._carrying:
                ended.append((event["track"],))
            at = self.origin + float(event["time_s"])
            rows.append((self.run, self._seq, at, float(event["time_s"]), event["event"], str(event["track"]),
                         json.dumps(event)))
            self._seq += 1
        self._add("events", rows, at_most=max((r[2] for r in rows), default=None))
        self._add("carried", ended)

    def positions(self, time_s: float, people, camera: str) -> None:
        """The people of a settled frame (``PersonNow``), each kept once per whole second of stream time."""
        second, rows, camera = int(time_s // 1.0), [], without_passwords(camera)
        if second != self._pruned_at:  # once a second: only who was seen in the last second is kept
            self._second = {track: kept for track, kept in self._second.items() if kept >= second - 1}
            self._pruned_at = second
        for person in people:
            if self._second.get(person.track) == second:
                continue
            self._second[person.track] = second
            sd = [float(v) for v in person.position_sd] if person.position_sd is not None else [None, None]
            rows.append((self.run, person.track, self.origin + time_s, float(person.joints[0, 0]),
                         float(person.joints[0, 1]), sd[0], sd[1], camera))
        self._add("positions", rows, at_most=self.origin + time_s if rows else None)

    def person(self, person: str, first_s: float, last_s: float, stature_m: float | None, stature_class: str,
               rejoins: int, camera: str) -> None:
        self._add("people", [(person, self.run, self.origin + first_s, self.origin + last_s, stature_m,
                              stature_class, int(rejoins), without_passwords(camera))])

    def gap(self, camera: str, from_at: float, to_at: float, why: str) -> None:
        self._add("gaps", [(self.run, without_passwords(camera), float(from_at), float(to_at), why)])

    def behind(self, camera: str, from_s: float, to_s: float, share: float) -> None:
        """A stretch of stream time in which the run could not keep up with ``camera`` (``share`` of its frames
        dropped): its counts are uncertain."""
        self._add("behind", [(self.run, without_passwords(camera), self.origin + float(from_s),
                              self.origin + float(to_s), float(share))])

    def floor(self, camera: str, centre, evidence, keypoints: str | None = None) -> None:
        """What a camera's people showed of the floor itself (``SizeEvidence`` and ``SeenTwice``), seen from its
        (3,) ``centre`` by a detector of ``keypoints`` (a layout)."""
        at, camera, centre = time.time(), without_passwords(camera), [float(v) for v in centre]
        rows = [(self.run, camera, at, "ankles" if isinstance(e, SeenTwice) else "people", *centre, keypoints,
                 *((None, None, e.height_m, e.sd_m) if isinstance(e, SeenTwice)
                   else (e.centre_z, e.log_size_over_drop, None, None)), e.seconds) for e in evidence]
        self._add("floor", rows)

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
        with self._lock:
            self._progress[source] = (int(frame), self.origin + time_s)
            if self._first_at is None:
                self._first_at = self.origin + time_s

    def _add(self, table: str, rows: list, at_most: float | None = None) -> None:
        if not rows:
            return
        with self._lock:
            if sum(len(waiting) for waiting in self._waiting.values()) + len(rows) > self.max_waiting:
                self.lost += len(rows)
                if self.lost == len(rows):
                    self.report(f"store {self.shown}: {self.max_waiting} rows wait to be written; "
                                "rows beyond are lost until it takes them")
                return
            self._waiting[table].extend(rows)
            if at_most is not None:
                self._last_at = max(self._last_at or at_most, at_most)

    # Committing.

    def _commit_every(self) -> None:
        while not self._stop.wait(self.commit_every_s):
            self.commit()

    def commit(self) -> bool:
        """Write what waits in one transaction; whether it was written (if not, it waits for the next)."""
        with self._lock:
            waiting = {table: list(rows) for table, rows in self._waiting.items()}
            progress, last_at = dict(self._progress), self._last_at
        if not any(waiting.values()) and not progress:
            return True
        try:
            if self._database is None:
                self._database = connect(self.location)
            self._write(self._database, waiting, progress, last_at)
        except Exception as err:  # the database unreachable or refusing: kept, tried again
            if not self._failed:
                self._failed = True
                self.report(f"store {self.shown}: cannot write ({type(err).__name__}: "
                            f"{str(err).strip().splitlines()[0] if str(err).strip() else ''}); trying again")
            if self._database is not None:
                self._database.close()
                self._database = None
            return False
        self._failed = False
        with self._lock:
            for table, rows in waiting.items():
                del self._waiting[table][:len(rows)]
                self.written[table] += len(rows)
            for source, value in progress.items():
                if self._progress.get(source) == value:
                    del self._progress[source]
        return True

    def _write(self, database: Database, waiting: dict, progress: dict, last_at: float | None) -> None:
        database.many("INSERT INTO events (run, seq, at, time_s, kind, person, body) VALUES (?, ?, ?, ?, ?, ?, ?)",
                      waiting["events"])
        database.many("INSERT INTO positions (run, person, at, x, y, sd_along, sd_across, camera) "
                      "VALUES (?, ?, ?, ?, ?, ?, ?, ?)", waiting["positions"])
        database.many("INSERT INTO people (person, run, first_at, last_at, stature_m, stature_class, rejoins, camera) "
                      "VALUES (?, ?, ?, ?, ?, ?, ?, ?) ON CONFLICT (person) DO UPDATE SET last_at = excluded.last_at, "
                      "stature_m = excluded.stature_m, stature_class = excluded.stature_class, "
                      "rejoins = excluded.rejoins", waiting["people"])
        database.many("INSERT INTO gaps (run, camera, from_at, to_at, why) VALUES (?, ?, ?, ?, ?)", waiting["gaps"])
        database.many("DELETE FROM carried WHERE person = ?", waiting["carried"])
        database.many("INSERT INTO behind (run, camera, from_at, to_at, dropped_share) VALUES (?, ?, ?, ?, ?)",
                      waiting["behind"])
        database.many("INSERT INTO floor_evidence (run, camera, at, kind, camera_x, camera_y, camera_z, keypoints, "
                      "centre_z, log_size_over_drop, height_m, sd_m, seconds) "
                      "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)", waiting["floor"])
        database.many("INSERT INTO progress (source, run, frame, at, origin) VALUES (?, ?, ?, ?, ?) "
                      "ON CONFLICT (source) DO UPDATE SET run = excluded.run, frame = excluded.frame, "
                      "at = excluded.at, origin = excluded.origin",
                      [(source, self.run, frame, at, self.origin) for source, (frame, at) in progress.items()])
        newest = max([at for _, at in progress.values()] + ([last_at] if last_at is not None else []), default=None)
        if newest is not None:
            database.execute("UPDATE runs SET last_at = ?, first_at = COALESCE(first_at, ?) WHERE run = ?",
                             (newest, self._first_at if self._first_at is not None else newest, self.run))
        database.commit()

    def discard(self) -> None:
        """A run that never started (its inputs could not be opened) taken out of the store; an SQLite store that
        holds nothing else is removed."""
        from pathlib import Path

        self._stop.set()
        self._committer.join()
        database = self._database or connect(self.location)
        database.execute("DELETE FROM runs WHERE run = ?", (self.run,))
        others = database.rows("SELECT COUNT(*) FROM runs")[0][0]
        database.commit()
        database.close()
        self._database = None
        self._writer.release()
        if not others and not database.postgresql:
            for path in (*(Path(f"{self.location}{suffix}") for suffix in ("", "-wal", "-shm")),
                         lock_path(self.location)):
                path.unlink(missing_ok=True)

    def close(self, ending: str) -> None:
        """Every row waiting written (tried for a few seconds where the database is down), the run's end noted.
        Closing again does nothing."""
        if self._stop.is_set():
            return
        self._stop.set()
        self._committer.join()
        for source, down_since in self._down_since.items():  # an input that gave no frame this run
            self.gap(source, down_since, max(down_since, time.time()), DOWN_BETWEEN_RUNS)
        self._down_since.clear()
        deadline = time.monotonic() + 5.0
        while not self.commit() and time.monotonic() < deadline:
            time.sleep(0.5)
        try:
            if self._database is None:
                self._database = connect(self.location)
            self._database.execute("UPDATE runs SET ended_at = ?, ending = ? WHERE run = ?",
                                   (time.time(), ending, self.run))
            self._database.commit()
        except Exception as err:
            self.report(f"store {self.shown}: the run's end could not be noted ({type(err).__name__})")
        finally:
            left = sum(len(rows) for rows in self._waiting.values())
            if left:
                self.report(f"store {self.shown}: {left} rows could not be written")
            if self._database is not None:
                self._database.close()
                self._database = None
            self._writer.release()  # the next run may begin
