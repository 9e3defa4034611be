"""The site's store: what a run hands over is committed within a second and read back as written, on SQLite and
on a real PostgreSQL alike; a run started again appends (ids unique, files taken up where they were left, the gap
between the runs recorded); a process killed outright loses at most its last second; the schema's version is kept
and migrated; what is not a store is refused in one line."""

from __future__ import annotations

import dataclasses
import json
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
from services import postgresql_server

from ray3d import InputError
from ray3d.geometry.uncertainty import PersonNow
from ray3d.store import RunRecorder, read_record, schema
from ray3d.store.database import connect
from ray3d.store.restart import take_over_cut_off_runs


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
    assert recorder.run == 1 and recorder.written == {"events": 2, "positions": 3, "people": 1, "gaps": 1,
                                                      "floor": 0, "behind": 0, "ended": 1}
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


def test_who_is_in_view_waits_as_one_row_a_person_and_is_let_go_when_they_leave_announced_or_not(tmp_path):
    """``in_view`` is state, not a record: each person's latest tracked floor point, one row a person however many
    frames wait (a long outage never fills the waiting rows with it), gone once they leave, even unannounced."""
    store = tmp_path / "site.db"
    recorder = RunRecorder(store, "ray3d live clip.avi", ["clip.avi"], [False], origin=1_000_000.0,
                           commit_every_s=3600.0)  # nothing committed until asked
    for frame in range(50):
        people = [dataclasses.replace(_person(name, 0.1 * frame, 1.0), tracked=np.array([0.1 * frame, 2.0, 1.0, 0.0]))
                  for name in ("1-0", "1-1")]
        recorder.positions(frame / 10, people, "cam")
    assert recorder._waiting.left() == 10  # the positions, once a second each; in_view not counted
    recorder.commit()
    with sqlite3.connect(store) as connection:
        assert sorted(connection.execute("SELECT person, x, y, vx, vy, clothes FROM in_view")) == [
            ("1-0", pytest.approx(4.9), 2.0, 1.0, 0.0, None), ("1-1", pytest.approx(4.9), 2.0, 1.0, 0.0, None)]
    recorder.left(["1-1"])  # followed for a moment, never announced: no "track ended" to let them go
    recorder.commit()
    with sqlite3.connect(store) as connection:
        assert [row[0] for row in connection.execute("SELECT person FROM in_view")] == ["1-0"]
    recorder.close("ended")


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
    # The first run's person, followed on and lifted from what this run saw of them: first seen in the first run.
    second.person("1-3", 4.2, 4.4, 1.7, "adult", 0, "cam")
    second.close("ended")
    record = read_record(store)
    assert [e["track"] for e in record.events] == ["1-3", "2-0"]  # nothing replaced, ids apart
    assert [(p["person"], p["first_at"], p["last_at"]) for p in record.people] == [("1-3", 501.0, 504.4)]
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
    with pytest.raises(InputError, match=r"schema version 99, written by a newer ray3d \(this one reads up to "
                                         rf"{schema.SCHEMA_VERSION}\)"):
        read_record(store)
    now = schema.SCHEMA_VERSION
    with sqlite3.connect(store) as connection:
        connection.execute("UPDATE store_meta SET value = ? WHERE name = 'schema_version'", (str(now),))
    # A next version that adds a column: a store of this one is migrated, its record kept.
    monkeypatch.setattr(schema, "SCHEMA_VERSION", now + 1)
    monkeypatch.setattr(schema, "MIGRATIONS", {**schema.MIGRATIONS, now: ("ALTER TABLE people ADD COLUMN note TEXT",)})
    from ray3d.store import database

    monkeypatch.setattr(database, "SCHEMA_VERSION", now + 1)
    monkeypatch.setattr(database, "MIGRATIONS", schema.MIGRATIONS)
    record = read_record(store)
    assert len(record.events) == 2
    with sqlite3.connect(store) as connection:
        assert connection.execute("SELECT value FROM store_meta WHERE name = 'schema_version'").fetchone() == (
            str(now + 1),)
        assert "note" in [row[1] for row in connection.execute("PRAGMA table_info(people)")]


HALL, DOOR = np.array([1.0, 2.0, 2.5]), np.array([6.0, 2.0, 1.2])  # two cameras' centres


def _floor_run(store, cameras: dict, ankles=()) -> RunRecorder:
    """A run whose cameras ({name: (centre, their people's SizeEvidence)}) saw ``ankles`` (SeenTwice) at once."""
    recorder = RunRecorder(store, "ray3d live", list(cameras), [False] * len(cameras))
    for name, (centre, people) in cameras.items():
        recorder.floor(name, centre, people, "coco17")
        recorder.floor(name, centre, ankles)  # a person two cameras saw is each camera's evidence
    recorder.close("ended")
    return recorder


def test_what_each_cameras_people_showed_of_the_floor_is_kept_run_after_run_where_the_camera_stands(tmp_path):
    from ray3d import body
    from ray3d.refine.ankle_plane import SeenTwice, SizeEvidence, observe_ankle_plane
    from ray3d.store import floor_decisions
    from ray3d.store.reader import remembered_floor

    store = tmp_path / "site.db"
    hall = tuple(SizeEvidence(2.5, float(np.log(1.6 / 2.5)) + d, 3.0) for d in (-0.05, 0.0, 0.05))
    door = (SizeEvidence(1.2, float(np.log(1.6 / 1.2)), 2.0),)
    twice = SeenTwice(0.02, 0.03, 1.5)
    first = _floor_run(store, {"hall": (HALL, hall), "door": (DOOR, door)}, (twice,))
    assert first.written["floor"] == len(hall) + len(door) + 2
    # A later run starts on it, where each camera stands (within 1 cm); the person seen by both counted once.
    assert set(remembered_floor(store, [("hall", HALL + [0.005, 0, 0])])) == {*hall, twice}
    both = remembered_floor(store, [("hall", HALL), ("door", DOOR)])
    assert len(both) == 5 and set(both) == {*hall, *door, twice}
    assert remembered_floor(store, [("door", DOOR + [0, 0, 0.02])]) == ()  # moved 2 cm: another calibration
    assert remembered_floor(store, [("hall", HALL)], kept=1) != () and len(remembered_floor(
        store, [("hall", HALL)], kept=1)) == 2  # the latest of each kind
    # ``ray3d site --store``: each camera's floor from all its runs, for its detector's keypoints.
    source = body.keypoint_source("coco17")
    decided = floor_decisions(store)
    assert list(decided) == ["door", "hall"]
    expected = observe_ankle_plane(list(hall), 0.0, source.planted_ankle_sd_m, body.ADULT_BODY_SIZE_M,
                                   source.read_size_sd, (twice,)).standing(source.planted_ankle_m)
    assert decided["hall"] == expected and decided["hall"].people == 3 and decided["hall"].seen_twice == 1
    assert "hall" in decided["hall"].message("hall")
    # The door moved: from its next run on, only what it showed where it stands now.
    _floor_run(store, {"door": (DOOR + [0.5, 0, 0], door * 2)})
    assert floor_decisions(store)["door"].people == 2 and floor_decisions(store)["door"].seen_twice == 0
    assert floor_decisions(store)["hall"] == expected


def test_an_older_store_without_the_floor_table_opens_and_gains_it(tmp_path):
    from ray3d.refine.ankle_plane import SizeEvidence
    from ray3d.store import floor_decisions

    store = tmp_path / "site.db"
    _one_run(store)
    with sqlite3.connect(store) as connection:  # as version 1 left it
        connection.execute("DROP TABLE floor_evidence")
        connection.execute("UPDATE store_meta SET value = '1' WHERE name = 'schema_version'")
    assert len(read_record(store).events) == 2 and floor_decisions(store) == {}
    again = RunRecorder(store, "ray3d live clip.avi", ["clip.avi"], [False])
    assert again.remembered_floor([("cam", HALL)]) == ()
    again.floor("cam", HALL, (SizeEvidence(2.5, -0.4, 2.0),), "h36m17")
    again.close("ended")
    with sqlite3.connect(store) as connection:
        assert connection.execute("SELECT value FROM store_meta WHERE name = 'schema_version'").fetchone() == (
            str(schema.SCHEMA_VERSION),)
    assert floor_decisions(store)["cam"].people == 1 and len(read_record(store).runs) == 2


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
        # what the cameras' people showed of the floor: the same decision from either
        from ray3d.refine.ankle_plane import SeenTwice, SizeEvidence
        from ray3d.store import floor_decisions

        seen = {"hall": (HALL, (SizeEvidence(2.5, -0.45, 3.0), SizeEvidence(2.5, -0.5, 2.0))),
                "door": (DOOR, (SizeEvidence(1.2, 0.3, 2.0),))}
        for location in (tmp_path / "floor.db", url):
            _floor_run(location, seen, (SeenTwice(0.02, 0.03, 1.5),))
        assert floor_decisions(url) == floor_decisions(tmp_path / "floor.db")
        assert floor_decisions(url)["hall"].people == 2 and floor_decisions(url)["hall"].seen_twice == 1


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


HOLDER = textwrap.dedent("""
    import sys, time
    from ray3d.store import RunRecorder
    recorder = RunRecorder(sys.argv[1], "the first service", ["rtsp://cam"], [False])
    print("writing", flush=True)
    time.sleep(600)
""")


def _one_writer_at_a_time(store, tmp_path) -> None:
    """A second recorder on ``store`` refused while a first (in this process, then in another one) writes it,
    naming the first; once that process is killed outright, the store opens at once."""
    import os
    import re
    import socket

    first = RunRecorder(store, "the first service", ["rtsp://cam"], [False])
    started = r"started \d{4}-\d\d-\d\dT\d\d:\d\d:\d\d[+-]\d\d:\d\d"
    with pytest.raises(InputError, match=rf"store: .+: ray3d live \(pid {os.getpid()} on "
                                         rf"{re.escape(socket.gethostname())}, {started}\) writes it; one process "
                                         "writes a store at a time"):
        RunRecorder(store, "the second", ["rtsp://cam"], [False])
    assert [r["command"] for r in read_record(store).runs] == ["the first service"]  # nothing of the second
    first.close("ended")
    holder = subprocess.Popen([sys.executable, "-c", HOLDER, str(store)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "writing"
        with pytest.raises(InputError, match=rf"\(pid {holder.pid} on "):
            RunRecorder(store, "while it writes", ["rtsp://cam"], [False])
        holder.send_signal(signal.SIGKILL)
        holder.wait()
        if str(store).startswith("postgresql://"):  # the server notices the connection gone
            time.sleep(0.5)
        opened = time.monotonic()
        again = RunRecorder(store, "restarted", ["rtsp://cam"], [False])  # not blocked by the killed one's lock
        assert time.monotonic() - opened < 2.0
        again.close("ended")
    finally:
        if holder.poll() is None:
            holder.kill()
            holder.wait()
    assert [r["command"] for r in read_record(store).runs] == ["the first service", "the first service", "restarted"]


def test_one_process_writes_a_store_a_second_refused_naming_it_a_killed_ones_lock_never_blocking(tmp_path, capsys):
    store = tmp_path / "site.db"
    _one_writer_at_a_time(store, tmp_path)
    # The command line: exit 2, one line naming the running one, before anything else is opened.
    from ray3d.cli import main

    holding = RunRecorder(store, "ray3d live", ["clip.mp4"], [True])
    try:
        assert main(["live", str(tmp_path / "clip.mp4"), "--camera", "h36m:S9:54138969", "--out", str(tmp_path),
                     "--no-page"]) == 2
        said = capsys.readouterr().err.strip().splitlines()
        assert len(said) == 1 and said[0].startswith(f"ray3d live: error: store: {store}: ray3d live (pid ") and \
            said[0].endswith("give this run another store (--store)")
    finally:
        holding.close("ended")
    assert main(["live", str(tmp_path / "clip.mp4"), "--camera", "h36m:S9:54138969", "--out", str(tmp_path),
                 "--no-page"]) == 2
    said = capsys.readouterr().err
    assert "writes it" not in said and "clip.mp4" in said  # past the store: what stops it now is the missing video


def test_one_process_writes_a_postgresql_store_its_lock_going_with_its_connection(tmp_path):
    with postgresql_server() as url:
        _one_writer_at_a_time(url, tmp_path)


CUT_OFF_WRITER = textwrap.dedent("""
    import sys, time
    import numpy as np
    from ray3d.geometry.uncertainty import PersonNow
    from ray3d.store import RunRecorder

    recorder = RunRecorder(sys.argv[1], "writer", ["cam"], [False], origin=1000.0)

    def event(kind, n, frame, **fields):
        return {"event": kind, "track": f"1-{n}", "time_s": frame / 10, "place_m": [n + frame / 100, 0.0],
                "frames": [frame], **fields}

    # Person n is seen from frame 10 n for 3 s; in the zone from 0.2 s on, leaving it at 1.5 s if n is even (an odd
    # one's visit ends with their track: no exit).
    for frame in range(100000):
        events, here = [], []
        for n in range(frame // 10 + 1):
            age = frame - 10 * n
            if age > 30:
                continue
            events += [event(kind, n, frame, **fields) for due, kind, fields in (
                (0, "track started", {}), (2, "zone entered", {"zone": "door"}),
                (15 if n % 2 == 0 else -1, "zone left", {"zone": "door", "dwell_s": 1.3}),
                (30, "track ended", {})) if due == age]
            if age < 30:
                joints = np.zeros((17, 3))
                joints[:, 0] = n + frame / 100
                # Where the tracker put them, walking at 0.1 m/s in clothes of their own (odd people only: a fused
                # person has none): beside the pelvis.
                tracked = np.array([n + frame / 100 + 0.5, 1.0, 0.1, 0.0]) if n % 2 else None
                clothes = np.eye(64)[n] if n % 2 else None
                here.append(PersonNow(f"1-{n}", joints, np.array([0.1, 0.1]), 1.7, tracked, clothes))
        recorder.events(events)
        recorder.positions(frame / 10, here, "cam")
        recorder.progress("cam", frame, frame / 10)
        print(frame, flush=True)
        time.sleep(0.01)
""")


def test_a_run_killed_outright_has_what_it_left_open_closed_by_the_next_at_its_last_commit(tmp_path):
    store = tmp_path / "site.db"
    writer = subprocess.Popen([sys.executable, "-c", CUT_OFF_WRITER, str(store)], stdout=subprocess.PIPE, text=True)
    while int(writer.stdout.readline()) < 75:  # persons 0-7 seen; 5, 6 and 7 in view
        pass
    writer.send_signal(signal.SIGKILL)
    writer.wait()
    before = read_record(store)
    started = {e["track"]: e for e in before.events if e["event"] == "track started"}
    open_tracks = set(started) - {e["track"] for e in before.events if e["event"] == "track ended"}
    visits = {(e["track"], e["zone"]): e for e in before.events if e["event"] == "zone entered"}
    open_visits = {visit for visit in visits if visit[0] in open_tracks} - \
        {(e["track"], e["zone"]) for e in before.events if e["event"] == "zone left"}
    assert len(open_tracks) >= 2 and open_visits and before.runs[0]["ending"] is None
    last_at = before.runs[0]["last_at"]
    last_place = {}
    for person, x, y in zip(before.positions["person"], before.positions["x"], before.positions["y"]):
        last_place[person] = [x, y]
    with sqlite3.connect(store) as connection:  # the tracked, as the next run's tracker finds people: preferred
        in_view = {person: [x, y] for person, x, y in connection.execute("SELECT person, x, y FROM in_view")}
    assert set(in_view) == {t for t in open_tracks if int(t.split("-")[1]) % 2}  # those ended are let go
    assert all(x == pytest.approx(last_place[t][0] + 0.5, abs=0.2) and y == 1.0 for t, (x, y) in in_view.items())
    copy = tmp_path / "copy.db"  # where a run taking the same file up carries them: both places
    with sqlite3.connect(store) as original, sqlite3.connect(copy) as copied:
        original.backup(copied)
    database = connect(copy)
    _, carried = take_over_cut_off_runs(database, carry=True)
    database.close()
    assert {c.person for c in carried} == open_tracks
    assert {c.person for c in carried if c.tracked} == set(in_view)
    assert all(list(c.tracked[:2]) == pytest.approx(in_view[c.person], abs=1e-3) for c in carried if c.tracked)
    assert all(c.walk == (0.1, 0.0) and c.clothes == tuple(np.eye(64)[int(c.person.split("-")[1])])
               for c in carried if c.tracked)
    assert all(c.walk is None and c.clothes is None for c in carried if not c.tracked)
    assert all(list(c.place) == pytest.approx(last_place[c.person]) for c in carried)

    again = RunRecorder(store, "writer", ["cam"], [False])
    closed = again.closed
    assert {e["track"] for e in closed if e["event"] == "track ended"} == open_tracks
    assert {(e["track"], e["zone"]) for e in closed if e["event"] == "zone left"} == open_visits
    for event in closed:
        assert event["reason"] == "the service stopped" and event["frames"] == []
        assert event["time_s"] == pytest.approx(last_at - 1000.0, abs=1e-3)  # at the last commit, on its clock
        assert event["place_m"] == pytest.approx(last_place[event["track"]], abs=1e-3)
        if event["event"] == "zone left":
            entered = visits[(event["track"], event["zone"])]
            assert event["dwell_s"] == pytest.approx(last_at - entered["at"], abs=1e-3)
    # Each visit's exit before its track's end, as a live run writes them.
    for track in open_tracks:
        mine = [e["event"] for e in closed if e["track"] == track]
        assert mine[-1] == "track ended" and all(kind == "zone left" for kind in mine[:-1])
    # What the next run begins on: the counts so far, its closing exits among them.
    entries = sum(e["event"] == "zone entered" for e in before.events)
    exits = sum(e["event"] == "zone left" for e in before.events) + len(open_visits)
    assert again.counted == {"door": {"entered": entries, "left": exits}}
    again.close("ended")
    after = read_record(store)
    ends = [e for e in after.events if e["event"] == "track ended"]
    assert sorted(e["track"] for e in ends) == sorted(started)  # every track started has its end
    assert all(e["run"] == 1 and e["at"] == pytest.approx(last_at) for e in after.events if "reason" in e)
    assert [r["ending"] for r in after.runs] == ["cut off", "ended"]
    with sqlite3.connect(store) as connection:
        assert connection.execute("SELECT COUNT(*) FROM in_view").fetchone() == (0,)
    third = RunRecorder(store, "writer", ["cam"], [False])  # nothing left open: nothing more closed
    assert third.closed == []
    third.close("ended")


def test_a_version_2_store_gains_the_falling_behind_table_and_a_run_records_its_stretches(tmp_path):
    """Schema 2 -> 3 (issue 68, item 1): a store written before the ``behind`` table gains it when opened, its
    record kept; a run's stretches of falling behind are read back on the store's clock."""
    store = tmp_path / "site.db"
    _one_run(store)
    with sqlite3.connect(store) as connection:
        connection.execute("DROP TABLE behind")
        connection.execute("DROP TABLE carried")
        connection.execute("DROP TABLE in_view")
        connection.execute("UPDATE store_meta SET value = '2' WHERE name = 'schema_version'")
    record = read_record(store)
    assert len(record.events) == 2 and record.behind == []
    with sqlite3.connect(store) as connection:
        assert connection.execute("SELECT value FROM store_meta WHERE name = 'schema_version'").fetchone() == (
            str(schema.SCHEMA_VERSION),)
        assert connection.execute("SELECT COUNT(*) FROM carried").fetchone() == (0,)  # and, in 4, the carried
        assert connection.execute("SELECT COUNT(*) FROM in_view").fetchone() == (0,)  # in 5, who is in view
    recorder = RunRecorder(store, "ray3d live clip.avi", ["clip.avi"], [False], origin=2_000_000.0)
    recorder.behind("cam", 12.5, 20.0, 0.23)
    recorder.close("ended")
    assert read_record(store).behind == [{"camera": "cam", "from_at": 2_000_012.5, "to_at": 2_000_020.0,
                                          "dropped_share": 0.23, "run": recorder.run}]


def test_a_version_5_store_gains_walks_and_clothes_in_view_its_record_kept_its_old_state_let_go(tmp_path):
    """Schema 5 -> 6 (issue 67): ``in_view`` is made anew with the walk and clothes the next run claims people by;
    it is state, so a version 5 row goes (a run cut off under version 5 has its people taken up by place alone)."""
    store = tmp_path / "site.db"
    _one_run(store)
    with sqlite3.connect(store) as connection:
        connection.execute("DROP TABLE in_view")
        connection.execute("CREATE TABLE in_view (person TEXT PRIMARY KEY, run INTEGER NOT NULL, "
                           "at DOUBLE PRECISION NOT NULL, x DOUBLE PRECISION NOT NULL, y DOUBLE PRECISION NOT NULL)")
        connection.execute("INSERT INTO in_view VALUES ('1-0', 1, 5.0, 1.0, 2.0)")
        connection.execute("UPDATE store_meta SET value = '5' WHERE name = 'schema_version'")
    assert len(read_record(store).events) == 2
    with sqlite3.connect(store) as connection:
        assert connection.execute("SELECT value FROM store_meta WHERE name = 'schema_version'").fetchone() == ("6",)
        assert [row[1] for row in connection.execute("PRAGMA table_info(in_view)")] == [
            "person", "run", "at", "x", "y", "vx", "vy", "clothes"]
        assert connection.execute("SELECT COUNT(*) FROM in_view").fetchone() == (0,)


def test_the_records_occupancy_is_the_live_monitors_at_each_recorded_second(tmp_path):
    """The store's report counts who is in a zone by the live monitor's rule (``site.in_zones``, issue 69): with
    buckets of a second, each bucket's occupancy is what the run's ``SiteMonitor`` had in the zone at the frame
    whose positions the store kept, those already inside when their track started too."""
    from ray3d.site import SiteMonitor, Zone
    from ray3d.site.places import Site
    from ray3d.site.record import record_buckets

    site = Site((Zone("room", np.array([[1.0, -2.0], [4.0, -2.0], [4.0, 2.0], [1.0, 2.0]])),))
    monitor = SiteMonitor(site, 10.0)
    recorder = RunRecorder(tmp_path / "site.db", "ray3d live clip.avi", ["clip.avi"], [False], origin=1_000_000.0)
    walks = {"in and out": lambda t: (0.5 * t, 0.0), "starts inside, leaves": lambda t: (3.0 + 0.3 * t, 1.0),
             "comes in late": lambda t: (5.0 - 0.4 * t, -1.0)}
    at_each_second = []
    for frame in range(100):
        people = [_person(f"1-{name}", *walk(frame / 10)) for name, walk in walks.items()]
        recorder.events(monitor.update(frame, {p.track: p.joints for p in people}))
        recorder.positions(frame / 10, people, "cam")
        recorder.progress("clip.avi", frame, frame / 10)
        if frame % 10 == 0:
            at_each_second.append(len(monitor.occupants["room"]))
    recorder.close("ended")
    buckets = record_buckets(read_record(tmp_path / "site.db"), site, 1.0)
    recorded = [b for b in buckets if b["recorded %"] == 100]
    assert len(recorded) >= 9 and len(set(at_each_second)) > 1  # people come and go
    assert [b["room: peak occupancy"] for b in recorded] == at_each_second[:len(recorded)]
    assert [b["room: mean occupancy"] for b in recorded] == at_each_second[:len(recorded)]
