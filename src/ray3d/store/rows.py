"""A live run's record as rows (``writer.RunRecorder`` stands on these): each table's rows made from what the
live loop hands over (``event_rows``, ``floor_rows``, a person's position once a second: ``OncePerSecond``), and
what waits written in one transaction (``write_rows``; when: ``committer``)."""

from __future__ import annotations

import json

import numpy as np

from ray3d.refine.ankle_plane import SeenTwice
from ray3d.site.events import TRACK_ENDED, TRACK_STARTED
from ray3d.store.database import Database

# The tables a run's rows wait for; "ended": the people whose tracks ended (their rows of ``carried`` and
# ``in_view`` are deleted). ``in_view`` itself waits as each person's latest row only (``WaitingRows.placed``).
WAITING_TABLES = ("events", "positions", "people", "gaps", "floor", "behind", "ended")


def event_rows(run: int, first_seq: int, origin: float, events: list[dict]) -> tuple[list, list]:
    """The ``events`` of run ``run`` as rows of ``events`` numbered from ``first_seq``, each dated at ``origin``
    (Unix time of frame 0) plus its ``time_s``, and the people whose tracks these events end (rows of ``ended``)."""
    rows, ended = [], []
    for seq, event in enumerate(events, start=first_seq):
        if event["event"] == TRACK_ENDED.name:
            ended.append((event["track"],))
        rows.append((run, seq, origin + float(event["time_s"]), float(event["time_s"]), event["event"],
                     str(event["track"]), json.dumps(event)))
    return rows, ended


def in_view_rows(run: int, at: float, people) -> list[tuple]:
    """Rows of ``in_view`` for the people of a settled frame (``PersonNow``) at Unix time ``at``: where their
    tracker placed them, the walk it read and their clothes' colours (a JSON list); none for a person fused from
    several cameras, or whom their tracker could not place."""
    return [(person.track, run, at, *map(float, person.tracked),
             None if person.clothes is None else json.dumps(np.round(person.clothes, 4).tolist()))
            for person in people if person.tracked is not None and np.isfinite(person.tracked).all()]


def floor_rows(run: int, camera: str, at: float, centre, evidence, keypoints: str | None) -> list[tuple]:
    """Rows of ``floor_evidence``: what a camera's people showed of the floor (``SizeEvidence`` and ``SeenTwice``),
    seen from its (3,) ``centre`` by a detector of ``keypoints`` (a layout), noted at Unix time ``at``."""
    centre = [float(v) for v in centre]
    return [(run, camera, at, "ankles" if isinstance(e, SeenTwice) else "people", *centre, keypoints,
             *((None, None, e.height_m, e.sd_m) if isinstance(e, SeenTwice)
               else (e.centre_z, e.log_size_over_drop, None, None)), e.seconds) for e in evidence]


class OncePerSecond:
    """Which people have had a position kept in the current whole second of stream time: each person's position
    is kept once a second (of those seen in the last second: who left is forgotten)."""

    def __init__(self):
        self._second: dict[str, int] = {}  # person -> the last whole second a position was kept
        self._pruned_at: int | None = None

    def keep(self, person: str, second: int) -> bool:
        """Whether ``person``'s position in whole second ``second`` is to be kept (the first of that second)."""
        if second != self._pruned_at:  # once a second: only who was seen in the last second is kept
            self._second = {track: kept for track, kept in self._second.items() if kept >= second - 1}
            self._pruned_at = second
        if self._second.get(person) == second:
            return False
        self._second[person] = second
        return True


def write_rows(database: Database, run: int, origin: float, first_at: float | None, rows: dict, progress: dict,
               last_at: float | None) -> None:
    """Run ``run``'s waiting ``rows`` (``committer.WaitingRows.taken``) and each input's ``progress`` (on the clock
    whose frame 0 is at Unix time ``origin``) written and committed in one transaction, with the run's first and
    newest times (``first_at``: its first frame, ``last_at``: its newest row)."""
    database.many("INSERT INTO events (run, seq, at, time_s, kind, person, body) VALUES (?, ?, ?, ?, ?, ?, ?)",
                  rows["events"])
    database.many("INSERT INTO positions (run, person, at, x, y, sd_along, sd_across, camera) "
                  "VALUES (?, ?, ?, ?, ?, ?, ?, ?)", rows["positions"])
    # A person followed across a cut-off run is lifted from the part the run that ends them saw: they were first
    # seen when their track started, in the run that began it.
    database.many("INSERT INTO people (person, run, first_at, last_at, stature_m, stature_class, rejoins, camera) "
                  "SELECT ?, ?, MIN(started), ?, ?, ?, ?, ? FROM (SELECT ? AS started UNION ALL SELECT at FROM events "
                  "WHERE person = ? AND kind = ?) AS starts WHERE true ON CONFLICT (person) DO UPDATE SET "
                  "last_at = excluded.last_at, stature_m = excluded.stature_m, stature_class = excluded.stature_class, "
                  "rejoins = excluded.rejoins",
                  [(person, run, last_at, stature, stature_class, rejoins, camera, first_at, person, TRACK_STARTED.name)
                   for person, run, first_at, last_at, stature, stature_class, rejoins, camera in rows["people"]])
    database.many("INSERT INTO gaps (run, camera, from_at, to_at, why) VALUES (?, ?, ?, ?, ?)", rows["gaps"])
    database.many("INSERT INTO in_view (person, run, at, x, y, vx, vy, clothes) VALUES (?, ?, ?, ?, ?, ?, ?, ?) "
                  "ON CONFLICT (person) DO UPDATE SET run = excluded.run, at = excluded.at, x = excluded.x, "
                  "y = excluded.y, vx = excluded.vx, vy = excluded.vy, clothes = excluded.clothes", rows["in_view"])
    database.many("DELETE FROM carried WHERE person = ?", rows["ended"])
    database.many("DELETE FROM in_view WHERE person = ?", rows["ended"])
    database.many("INSERT INTO behind (run, camera, from_at, to_at, dropped_share) VALUES (?, ?, ?, ?, ?)",
                  rows["behind"])
    database.many("INSERT INTO floor_evidence (run, camera, at, kind, camera_x, camera_y, camera_z, keypoints, "
                  "centre_z, log_size_over_drop, height_m, sd_m, seconds) "
                  "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)", rows["floor"])
    database.many("INSERT INTO progress (source, run, frame, at, origin) VALUES (?, ?, ?, ?, ?) "
                  "ON CONFLICT (source) DO UPDATE SET run = excluded.run, frame = excluded.frame, "
                  "at = excluded.at, origin = excluded.origin",
                  [(source, run, frame, at, origin) for source, (frame, at) in progress.items()])
    newest = max([at for _, at in progress.values()] + ([last_at] if last_at is not None else []), default=None)
    if newest is not None:
        database.execute("UPDATE runs SET last_at = ?, first_at = COALESCE(first_at, ?) WHERE run = ?",
                         (newest, first_at if first_at is not None else newest, run))
    database.commit()
