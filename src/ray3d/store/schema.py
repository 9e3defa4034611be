"""The site store's tables, one schema for SQLite and PostgreSQL, its version and the steps from each older
version to the next (``MIGRATIONS``). Times are Unix seconds (``at``); a run's stream clock (``time_s``) is kept
beside them as the events carry it.

- ``store_meta``: the schema's version, and the process writing the store now or last (``writer``: its pid, host
  and start, JSON), named when a second one is refused (``lock``).
- ``runs``: one row per ``ray3d live`` process on the store: when it started, what it followed, how it ended
  (NULL while it runs; "cut off" once the next run found it killed and closed what it left open) and the span of
  stream time it recorded (``first_at`` to ``last_at``, the newest moment committed).
- ``events``: every site event as it happened (its JSON as written to events.jsonl), numbered within its run; the
  tracks and visits a run cut off left open end in events of that run with ``reason`` "the service stopped"
  (``restart``).
- ``positions``: each person's floor point once per second of stream time, with its standard deviation along and
  across the camera's ray and the camera(s) that saw it.
- ``people``: one row per person (ids unique across runs): first and last seen, stature, class, re-joins.
- ``gaps``: where the record has none: a camera's stream down, or the service down between two runs.
- ``progress``: per input, the last frame recorded, and the wall-clock time of its frame 0: a file followed again
  is taken up where it was left, on the same clock.
- ``floor_evidence`` (version 2): what each camera's people showed of the floor itself (issue 66), one row per
  person lifted (``kind`` "people": ``refine.ankle_plane.SizeEvidence``'s ``centre_z``, ``log_size_over_drop``,
  ``seconds``) and per person two cameras saw at once, under each of the two (``kind`` "ankles": ``SeenTwice``'s
  ``height_m``, ``sd_m``, ``seconds``), with the camera's centre it was seen from (``camera_x/y/z``: a camera
  moved or recalibrated starts afresh) and the ``keypoints`` layout of its detector (its planted ankle's height).
- ``behind`` (version 3): each stretch in which a run could not keep up with a camera's stream (more than 2 % of
  its frames dropped over 10 s, ``live.health``): its camera, start and end (``from_at``, ``to_at``) and the share
  of its frames dropped over it; the counts of that time are uncertain (the store's report shades it).
- ``carried`` (version 4): the people a run cut off left in view that a later run took up with their ids (``restart``),
  each with the run their track began in, until their track ends.
- ``in_view`` (version 5): each person in view, where their camera's tracker last placed them on the floor (the
  point between the ankles, ``x``, ``y``, at ``at``), until their track ends: where a run cut off left them, in the
  terms the next run's tracker finds people in (``positions`` holds the lifted pelvis, once a second); since
  version 6 also the walk it read there (``vx``, ``vy``, m/s) and their clothes' colours (``clothes``: the tracker's
  histogram as a JSON list), so that the next run knows who is who among people near each other. Its rows are
  state, not record: version 6 makes it anew (a store cut off under version 5 has its people taken up by their
  places alone)."""

from __future__ import annotations

SCHEMA_VERSION = 6

FLOOR_EVIDENCE = (
    "CREATE TABLE IF NOT EXISTS floor_evidence (run INTEGER NOT NULL, camera TEXT NOT NULL, "
    "at DOUBLE PRECISION NOT NULL, kind TEXT NOT NULL, camera_x DOUBLE PRECISION NOT NULL, "
    "camera_y DOUBLE PRECISION NOT NULL, camera_z DOUBLE PRECISION NOT NULL, keypoints TEXT, "
    "centre_z DOUBLE PRECISION, log_size_over_drop DOUBLE PRECISION, height_m DOUBLE PRECISION, "
    "sd_m DOUBLE PRECISION, seconds DOUBLE PRECISION NOT NULL)",
    "CREATE INDEX IF NOT EXISTS floor_evidence_camera ON floor_evidence (camera)",
)

BEHIND = (
    "CREATE TABLE IF NOT EXISTS behind (run INTEGER NOT NULL, camera TEXT NOT NULL, "
    "from_at DOUBLE PRECISION NOT NULL, to_at DOUBLE PRECISION NOT NULL, dropped_share DOUBLE PRECISION NOT NULL)",
)

CARRIED = ("CREATE TABLE IF NOT EXISTS carried (person TEXT PRIMARY KEY, run INTEGER NOT NULL)",)

IN_VIEW = ("CREATE TABLE IF NOT EXISTS in_view (person TEXT PRIMARY KEY, run INTEGER NOT NULL, "
           "at DOUBLE PRECISION NOT NULL, x DOUBLE PRECISION NOT NULL, y DOUBLE PRECISION NOT NULL, "
           "vx DOUBLE PRECISION, vy DOUBLE PRECISION, clothes TEXT)",)

# ``{id}``: the dialect's auto-numbered primary key (SQLite's rowid alias; PostgreSQL's identity column).
TABLES = (
    "CREATE TABLE IF NOT EXISTS store_meta (name TEXT PRIMARY KEY, value TEXT NOT NULL)",
    "CREATE TABLE IF NOT EXISTS runs (run {id}, started_at DOUBLE PRECISION NOT NULL, command TEXT NOT NULL, "
    "sources TEXT NOT NULL, site TEXT, ended_at DOUBLE PRECISION, ending TEXT, first_at DOUBLE PRECISION, "
    "last_at DOUBLE PRECISION)",
    "CREATE TABLE IF NOT EXISTS events (run INTEGER NOT NULL, seq INTEGER NOT NULL, at DOUBLE PRECISION NOT NULL, "
    "time_s DOUBLE PRECISION NOT NULL, kind TEXT NOT NULL, person TEXT NOT NULL, body TEXT NOT NULL, "
    "PRIMARY KEY (run, seq))",
    "CREATE INDEX IF NOT EXISTS events_at ON events (at)",
    "CREATE TABLE IF NOT EXISTS positions (run INTEGER NOT NULL, person TEXT NOT NULL, "
    "at DOUBLE PRECISION NOT NULL, x DOUBLE PRECISION NOT NULL, y DOUBLE PRECISION NOT NULL, "
    "sd_along DOUBLE PRECISION, sd_across DOUBLE PRECISION, camera TEXT NOT NULL)",
    "CREATE INDEX IF NOT EXISTS positions_at ON positions (at)",
    "CREATE TABLE IF NOT EXISTS people (person TEXT PRIMARY KEY, run INTEGER NOT NULL, "
    "first_at DOUBLE PRECISION NOT NULL, last_at DOUBLE PRECISION NOT NULL, stature_m DOUBLE PRECISION, "
    "stature_class TEXT NOT NULL, rejoins INTEGER NOT NULL, camera TEXT NOT NULL)",
    "CREATE TABLE IF NOT EXISTS gaps (run INTEGER NOT NULL, camera TEXT NOT NULL, "
    "from_at DOUBLE PRECISION NOT NULL, to_at DOUBLE PRECISION NOT NULL, why TEXT NOT NULL)",
    "CREATE TABLE IF NOT EXISTS progress (source TEXT PRIMARY KEY, run INTEGER NOT NULL, frame INTEGER NOT NULL, "
    "at DOUBLE PRECISION NOT NULL, origin DOUBLE PRECISION NOT NULL)",
    *FLOOR_EVIDENCE,
    *BEHIND,
    *CARRIED,
    *IN_VIEW,
)

# version -> the statements that take a store of that version to the next. Version 1 is the first.
MIGRATIONS: dict[int, tuple[str, ...]] = {1: FLOOR_EVIDENCE, 2: BEHIND, 3: CARRIED, 4: IN_VIEW,
                                          5: ("DROP TABLE IF EXISTS in_view", *IN_VIEW)}
