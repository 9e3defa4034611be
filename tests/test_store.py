"""The site's store: what a run hands over is committed within a second and read back as written, on SQLite and
on a real PostgreSQL alike; a run started again appends (ids unique, files taken up where they were left, the gap
between the runs recorded); a process killed outright loses at most its last second; the schema's version is kept
and migrated; what is not a store is refused in one line."""

from __future__ import annotations

import json
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from ray3d import InputError
from ray3d.geometry.uncertainty import PersonNow
from ray3d.store import RunRecorder, read_record
from ray3d.store import schema

from services import postgresql_server


def _person(track: str, x: float, y: float) -> PersonNow:
    joints = np.zeros((17, 3))
    joints[:, :2] = x, y
    return PersonNow(track, joints, np.array([0.3, 0.05]), 1.7)


def _event(kind: str, track: str, time_s: float) -> dict:
    return {"event": kind, "track": track, "time_s": time_s, "place_m": [1.0, 2.0], "frames": [int(time_s * 10)]}


def _one_run(location, origin: float = 1_000_000.0, frames: int = 30, source: str = "clip.avi") -> RunRecorder:
    """A run that sees one person walking for ``frames`` frames at 10 frames/s."""
    recorder = RunRecorder(location, "ray3d live clip.avi", [source], [False], origin=origin)
    prefix = recorder.id_prefix
    recorder.events([_event("track started", f"{prefix}0", 0.0)])
    for frame in range(frames):
        time_s = frame / 10
        recorder.positions(time_s, [_person(f"{prefix}0", 0.1 * frame, 1.0)], "cam")
        recorder.progress(source, frame, time_s)
    recorder.events([_event("track ended", f"{prefix}0", (frames - 1) / 10)])
    recorder.person(f"{prefix}0", 0.0, (frames - 1) / 10, 1.7, "adult", 0, "cam")
    recorder.gap("cam", origin + 1.0, origin + 1.5, "the stream was down")
    recorder.close("ended")
    return recorder


def test_a_run_is_read_back_as_written(tmp_path):
    store = tmp_path / "site.db"
    recorder = _one_run(store)
    record = read_record(store)
    assert recorder.run == 1 and recorder.written == {"events": 2, "positions": 3, "people": 1, "gaps": 1}
    assert [e["event"] for e in record.events] == ["track started", "track ended"]
    assert record.events[1]["at"] == pytest.approx(1_000_000.0 + 2.9) and record.events[0]["track"] == "1-0"
    # one position per whole second of stream time: frames 0, 10 and 20
    np.testing.assert_allclose(record.positions["at"] - 1_000_000.0, [0.0, 1.0, 2.0])
    np.testing.assert_allclose(record.positions["x"], [0.0, 1.0, 2.0])
    np.testing.assert_allclose(record.positions["sd_along"], 0.3)
    assert record.people[0]["person"] == "1-0" and record.people[0]["stature_class"] == "adult"
    assert record.gaps == [{"camera": "cam", "from_at": 1_000_001.0, "to_at": 1_000_001.5,
                            "why": "the stream was down", "run": 1}]
    run = record.runs[0]
    assert run["ending"] == "ended" and run["first_at"] == 1_000_000.0 and run["last_at"] == pytest.approx(1_000_002.9)
    with sqlite3.connect(store) as connection:
        assert connection.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    # a period: only what lies in it
    assert [e["event"] for e in read_record(store, 1_000_001.0, 1_000_010.0).events] == ["track ended"]


def test_a_run_started_again_appends_and_takes_a_file_up_where_it_was_left(tmp_path):
    store = tmp_path / "site.db"
    first = RunRecorder(store, "ray3d live a.avi", ["a.avi", "rtsp://cam"], [True, False], origin=500.0)
    first.events([_event("track started", f"{first.id_prefix}3", 1.0)])
    first.progress("a.avi", 41, 4.1)
    first.progress("rtsp://cam", 40, 4.0)
    first.close("stopped")
    assert not first.continues
    second = RunRecorder(store, "ray3d live a.avi", ["a.avi", "rtsp://cam"], [True, False])
    assert second.run == 2 and second.continues and second.id_prefix == "2-"
    assert second.resumes[0].first_index == 42 and second.resumes[0].origin == 500.0  # the file: on its clock
    assert second.resumes[1].first_index == 0  # a stream starts again now
    second.events([_event("track started", f"{second.id_prefix}0", 4.2)])
    second.progress("a.avi", 42, 4.2)
    second.close("ended")
    record = read_record(store)
    assert [e["track"] for e in record.events] == ["1-3", "2-0"]  # nothing replaced, ids apart
    down = [g for g in record.gaps if g["why"] == "the service was down"]
    assert sorted(g["camera"] for g in down) == ["a.avi", "rtsp://cam"]
    file_gap = next(g for g in down if g["camera"] == "a.avi")
    assert file_gap["from_at"] == pytest.approx(504.1) and file_gap["to_at"] == pytest.approx(504.2)
    assert [r["ending"] for r in record.runs] == ["stopped", "ended"]


KILLED_WRITER = textwrap.dedent("""
    import sys, time
    from ray3d.store import RunRecorder
    recorder = RunRecorder(sys.argv[1], "writer", ["clip.avi"], [True], origin=0.0)
    for n in range(100000):
        recorder.events([{"event": "track started", "track": str(n), "time_s": n / 100}])
        recorder.progress("clip.avi", n, n / 100)
        print(n, time.time(), flush=True)
        time.sleep(0.01)
""")


def test_a_process_killed_outright_loses_at_most_its_last_second(tmp_path):
    store = tmp_path / "site.db"
    writer = subprocess.Popen([sys.executable, "-c", KILLED_WRITER, str(store)], stdout=subprocess.PIPE, text=True)
    handed: list[tuple[int, float]] = []
    while len(handed) < 250:
        line = writer.stdout.readline()
        n, at = line.split()
        handed.append((int(n), float(at)))
    writer.send_signal(signal.SIGKILL)
    killed_at = time.time()
    writer.wait()
    handed += [(int(n), float(at)) for n, at in (line.split() for line in writer.stdout.read().splitlines())]
    record = read_record(store)
    kept = [int(e["track"]) for e in record.events]
    assert kept == list(range(len(kept)))  # in order, none lost in between, none twice
    before_last_second = [n for n, at in handed if at < killed_at - 1.0]
    assert before_last_second and kept[-1] >= before_last_second[-1]
    assert record.runs[0]["ending"] is None  # killed: no end noted
    again = RunRecorder(store, "writer", ["clip.avi"], [True])  # taken up after the last frame committed
    assert again.resumes[0].first_index == kept[-1] + 1
    again.close("ended")


def test_the_schema_version_is_kept_a_newer_store_refused_and_an_older_migrated(tmp_path, monkeypatch):
    store = tmp_path / "site.db"
    _one_run(store)
    with sqlite3.connect(store) as connection:
        assert connection.execute("SELECT value FROM store_meta WHERE name = 'schema_version'").fetchone() == (
            str(schema.SCHEMA_VERSION),)
        connection.execute("UPDATE store_meta SET value = '99' WHERE name = 'schema_version'")
    with pytest.raises(InputError, match=r"schema version 99, written by a newer ray3d \(this one reads up to 1\)"):
        read_record(store)
    with sqlite3.connect(store) as connection:
        connection.execute("UPDATE store_meta SET value = '1' WHERE name = 'schema_version'")
    # A version 2 that adds a column: a version 1 store is migrated, its record kept.
    monkeypatch.setattr(schema, "SCHEMA_VERSION", 2)
    monkeypatch.setattr(schema, "MIGRATIONS", {1: ("ALTER TABLE people ADD COLUMN note TEXT",)})
    from ray3d.store import database

    monkeypatch.setattr(database, "SCHEMA_VERSION", 2)
    monkeypatch.setattr(database, "MIGRATIONS", schema.MIGRATIONS)
    record = read_record(store)
    assert len(record.events) == 2
    with sqlite3.connect(store) as connection:
        assert connection.execute("SELECT value FROM store_meta WHERE name = 'schema_version'").fetchone() == ("2",)
        assert "note" in [row[1] for row in connection.execute("PRAGMA table_info(people)")]


def test_what_is_not_a_store_is_refused_in_one_line(tmp_path, capsys):
    from ray3d.cli import main

    text = tmp_path / "notes.db"
    text.write_text("not a database " * 100)
    with pytest.raises(InputError, match="notes.db: not an SQLite store"):
        read_record(text)
    with pytest.raises(InputError, match="no such store"):
        read_record(tmp_path / "missing.db")
    with pytest.raises(InputError, match="postgresql://ray3d@127.0.0.1:9/x: cannot connect"):
        read_record("postgresql://ray3d:secret@127.0.0.1:9/x")  # the password never said
    site = tmp_path / "site.json"
    site.write_text(json.dumps({"zones": [{"name": "a", "polygon": [[0, 0], [1, 0], [1, 1]]}]}))
    assert main(["site", "--store", str(text), "--site", str(site), "--out", str(tmp_path / "report")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "notes.db: not an SQLite store" in err[0]
    assert main(["site", "--site", str(site), "--out", str(tmp_path / "report")]) == 2
    assert capsys.readouterr().err.strip() == "ray3d site: error: give a world file or --store (one of them)"


def test_the_same_run_gives_the_same_record_on_postgresql_as_on_sqlite(tmp_path):
    with postgresql_server() as url:
        on_sqlite, on_postgresql = _one_run(tmp_path / "site.db"), _one_run(url)
        assert on_sqlite.written == on_postgresql.written
        lite, postgres = read_record(tmp_path / "site.db"), read_record(url)
        assert lite.events == postgres.events and lite.people == postgres.people and lite.gaps == postgres.gaps
        for key in ("at", "x", "y", "sd_along", "sd_across"):
            np.testing.assert_array_equal(lite.positions[key], postgres.positions[key])
        assert [r["ending"] for r in postgres.runs] == ["ended"]
        # two processes' runs on one PostgreSQL site: numbered apart
        again = _one_run(url, source="other.avi")
        assert again.run == 2 and {e["track"] for e in read_record(url).events} == {"1-0", "2-0"}


def test_no_password_of_a_stream_or_a_database_is_recorded_or_said(tmp_path):
    from ray3d.store.database import shown, without_passwords

    assert without_passwords("ray3d live rtsp://admin:s3cret@cam.local:554/live --store postgresql://me:pw@db/x") == \
        "ray3d live rtsp://admin@cam.local:554/live --store postgresql://me@db/x"
    assert without_passwords("rtsp://cam.local/live") == "rtsp://cam.local/live"
    assert shown("postgresql://me:pw@db:5432/site") == "postgresql://me@db:5432/site"
    source = "rtsp://admin:s3cret@cam.local/live"
    recorder = RunRecorder(tmp_path / "site.db", f"ray3d live {source}", [source], [False])
    recorder.events([_event("track started", "1-0", 0.0)])
    recorder.progress(source, 0, 0.0)
    recorder.gap(source, 1.0, 2.0, "the stream was down")
    recorder.close("ended")
    again = RunRecorder(tmp_path / "site.db", f"ray3d live {source}", [source], [False])  # the same input, known
    assert again.continues
    again.close("ended")
    assert b"s3cret" not in b"".join(path.read_bytes() for path in tmp_path.iterdir())
    assert read_record(tmp_path / "site.db").gaps[0]["camera"] == "rtsp://admin@cam.local/live"
