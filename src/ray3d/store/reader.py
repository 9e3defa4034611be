"""A site store read back over a period (``read_record``): its runs, events, positions, people and gaps, what
``ray3d site --store`` reports on; and what each camera's people showed of the floor run after run
(``remembered_floor``: a live run starts on it; ``floor_decisions``: each camera's floor as all of it decides)."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from ray3d import body
from ray3d.errors import InputError
from ray3d.io.floor_memory import SAME_CAMERA_M
from ray3d.refine.ankle_plane import AnklePlane, SeenTwice, SizeEvidence, observe_ankle_plane
from ray3d.store.database import connect, is_postgresql, shown

# The latest people (and people seen twice) per camera a run starts on: the shared part of the evidence (a
# site's population, the detector) does not shrink with more, and a live run keeps as many of its own.
REMEMBERED_PER_CAMERA = 500


@dataclasses.dataclass
class StoredRecord:
    """What a store holds from ``from_at`` to ``to_at`` (Unix seconds): ``events`` (each as written, with its
    ``at`` and ``run``), ``positions`` (N,) structured: at, x, y, sd_along, sd_across, person, camera; ``people``
    rows; ``gaps`` (camera, from_at, to_at, why, run) overlapping the period; ``runs``; ``behind`` (camera,
    from_at, to_at, dropped_share, run): the stretches overlapping it in which a run could not keep up (their counts
    uncertain)."""

    location: str
    from_at: float
    to_at: float
    runs: list[dict]
    events: list[dict]
    positions: dict[str, np.ndarray]
    people: list[dict]
    gaps: list[dict]
    behind: list[dict] = dataclasses.field(default_factory=list)


def read_record(location, from_at: float | None = None, to_at: float | None = None) -> StoredRecord:
    """The store at ``location`` (a file or a ``postgresql://`` URL) over [``from_at``, ``to_at``) (Unix seconds;
    None: from its first record / to its last)."""
    database = _opened(location)
    try:
        low = -math.inf if from_at is None else float(from_at)
        high = math.inf if to_at is None else float(to_at)
        bounds = (max(low, -1e300), min(high, 1e300))
        runs = [dict(zip(("run", "started_at", "command", "sources", "site", "ended_at", "ending", "first_at",
                          "last_at"), row))
                for row in database.rows("SELECT run, started_at, command, sources, site, ended_at, ending, first_at, "
                                         "last_at FROM runs ORDER BY run")]
        events = []
        for run, at, text in database.rows("SELECT run, at, body FROM events WHERE at >= ? AND at < ? "
                                           "ORDER BY at, run, seq", bounds):
            events.append({**json.loads(text), "at": float(at), "run": int(run)})
        rows = database.rows("SELECT at, x, y, sd_along, sd_across, person, camera FROM positions "
                             "WHERE at >= ? AND at < ? ORDER BY at", bounds)
        numbers = np.array([r[:5] for r in rows], dtype=float).reshape(-1, 5)
        positions = {"at": numbers[:, 0], "x": numbers[:, 1], "y": numbers[:, 2], "sd_along": numbers[:, 3],
                     "sd_across": numbers[:, 4], "person": np.array([r[5] for r in rows], dtype=object),
                     "camera": np.array([r[6] for r in rows], dtype=object)}
        people = [dict(zip(("person", "run", "first_at", "last_at", "stature_m", "stature_class", "rejoins",
                            "camera"), row))
                  for row in database.rows("SELECT person, run, first_at, last_at, stature_m, stature_class, "
                                           "rejoins, camera FROM people WHERE last_at >= ? AND first_at < ? "
                                           "ORDER BY first_at", bounds)]
        gaps = [dict(zip(("camera", "from_at", "to_at", "why", "run"), row))
                for row in database.rows("SELECT camera, from_at, to_at, why, run FROM gaps "
                                         "WHERE to_at >= ? AND from_at < ? ORDER BY from_at", bounds)]
        behind = [dict(zip(("camera", "from_at", "to_at", "dropped_share", "run"), row))
                  for row in database.rows("SELECT camera, from_at, to_at, dropped_share, run FROM behind "
                                           "WHERE to_at >= ? AND from_at < ? ORDER BY from_at", bounds)]
    finally:
        database.close()
    recorded = [*positions["at"], *(e["at"] for e in events)]
    first = low if math.isfinite(low) else min(recorded, default=0.0)
    last = high if math.isfinite(high) else max(recorded, default=first)
    return StoredRecord(shown(location), float(first), float(last), runs, events, positions, people, gaps, behind)


def _camera_floor(database, camera: str, centre, kept: int) -> tuple[list, list]:
    """One camera's latest ``kept`` rows of each kind seen from ``centre`` (within ``SAME_CAMERA_M``): its people's
    ``SizeEvidence`` and its ``SeenTwice``, each with its row's run."""
    found = {}
    for kind in ("people", "ankles"):
        box = [v for c in centre for v in (float(c) - SAME_CAMERA_M, float(c) + SAME_CAMERA_M)]
        rows = database.rows("SELECT run, at, camera_x, camera_y, camera_z, centre_z, log_size_over_drop, height_m, "
                             "sd_m, seconds FROM floor_evidence WHERE camera = ? AND kind = ? AND camera_x BETWEEN ? "
                             "AND ? AND camera_y BETWEEN ? AND ? AND camera_z BETWEEN ? AND ? ORDER BY at DESC LIMIT ?",
                             (camera, kind, *box, kept))
        here = [r for r in rows if np.linalg.norm(np.subtract(r[2:5], centre)) <= SAME_CAMERA_M]
        found[kind] = [(r[0], SizeEvidence(r[5], r[6], r[9]) if kind == "people"
                        else SeenTwice(r[7], r[8], r[9])) for r in here]
    return found["people"], found["ankles"]


def remembered_floor(location, cameras: list[tuple[str, object]], kept: int = REMEMBERED_PER_CAMERA) -> tuple:
    """What earlier runs' people showed of the floor of ``cameras`` (each its name and (3,) centre, as it stands
    now: a camera moved by more than ``SAME_CAMERA_M`` starts afresh), as ``LiftOptions.seen_before`` takes it:
    each camera's latest ``kept`` people and people seen twice (one seen by two of them counted once)."""
    database = connect(location)
    try:
        people, ankles = [], {}
        for camera, centre in cameras:
            found, twice = _camera_floor(database, camera, centre, kept)
            people += [e for _, e in found]
            ankles.update({(run, e): e for run, e in twice})  # both cameras' row of one crossing: once
    finally:
        database.close()
    return (*people, *ankles.values())


def floor_decisions(location, kept: int = REMEMBERED_PER_CAMERA) -> dict[str, AnklePlane]:
    """Each camera of the store at ``location``: its floor as its people in every run decided it, seen from where
    the camera stood last (``observe_ankle_plane`` on its latest ``kept`` people and people seen twice): for its
    detector's keypoints where the store knows them (``AnklePlane.message`` says it), else the floor's own plane
    (contact 0)."""
    database = _opened(location)
    try:
        decided = {}
        for (camera,) in database.rows("SELECT DISTINCT camera FROM floor_evidence ORDER BY camera"):
            centre = database.rows("SELECT camera_x, camera_y, camera_z FROM floor_evidence WHERE camera = ? "
                                   "ORDER BY at DESC LIMIT 1", (camera,))[0]
            known = database.rows("SELECT keypoints FROM floor_evidence WHERE camera = ? AND keypoints IS NOT NULL "
                                  "ORDER BY at DESC LIMIT 1", (camera,))
            source = body.keypoint_source(known[0][0] if known else "")
            people, ankles = _camera_floor(database, camera, centre, kept)
            floor = observe_ankle_plane([e for _, e in people], 0.0, source.planted_ankle_sd_m,
                                        body.ADULT_BODY_SIZE_M, source.read_size_sd, tuple(e for _, e in ankles))
            decided[camera] = floor.standing(source.planted_ankle_m) if known else floor
    finally:
        database.close()
    return decided


COPIED_TABLES = {"runs": ("run", "started_at", "command", "sources", "site", "ended_at", "ending", "first_at",
                          "last_at"),
                 "events": ("run", "seq", "at", "time_s", "kind", "person", "body"),
                 "positions": ("run", "person", "at", "x", "y", "sd_along", "sd_across", "camera"),
                 "people": ("person", "run", "first_at", "last_at", "stature_m", "stature_class", "rejoins",
                            "camera"),
                 "gaps": ("run", "camera", "from_at", "to_at", "why"),
                 "progress": ("source", "run", "frame", "at", "origin"),
                 "behind": ("run", "camera", "from_at", "to_at", "dropped_share"),
                 "floor_evidence": ("run", "camera", "at", "kind", "camera_x", "camera_y", "camera_z", "keypoints",
                                    "centre_z", "log_size_over_drop", "height_m", "sd_m", "seconds")}


def copy_record(source, target) -> dict[str, int]:
    """Every row of the store at ``source`` into a new, empty store at ``target`` (say from SQLite to PostgreSQL
    as a site grows), in one transaction; the rows copied per table. A ``target`` holding runs is refused."""
    reading, writing = _opened(source), connect(target)
    try:
        if writing.rows("SELECT COUNT(*) FROM runs")[0][0]:
            raise InputError(f"copy_to: {shown(target)}: holds a record already; copy into an empty store",
                             ("copy_to",))
        copied = {}
        for table, columns in COPIED_TABLES.items():
            rows = reading.rows(f"SELECT {', '.join(columns)} FROM {table}")
            writing.many(f"INSERT INTO {table} ({', '.join(columns)}) VALUES ({', '.join('?' * len(columns))})",
                         [tuple(row) for row in rows])
            copied[table] = len(rows)
        if writing.postgresql:  # run numbers go on after the copied ones
            writing.execute("SELECT setval(pg_get_serial_sequence('runs', 'run'), "
                            "(SELECT COALESCE(MAX(run), 0) + 1 FROM runs), false)")
        writing.commit()
        return copied
    finally:
        reading.close()
        writing.close()


def _opened(location):
    """The store at ``location`` connected; a file that is not there refused (connecting would make one)."""
    if not is_postgresql(location) and not Path(location).is_file():
        raise InputError(f"store: {location}: no such store", ("store",))
    return connect(location)
