"""A site that runs for months: a live run records to its store, and one started again on the same output appends
(nothing overwritten, ids apart, the gap between them recorded) and ``ray3d site --store`` reports over both; two
cameras on one walk count exactly what one counts; a stream served over RTSP that goes down three times is
reopened three times, each gap recorded, nobody counted across one; events on MQTT, in order, the occupancy
retained and the zones and lines announced to Home Assistant; a run killed outright closed by its restart, the
counts on MQTT going on; --until; and no image anywhere."""

from __future__ import annotations

import json
import re
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from browser import CHROMIUM, console_errors
from services import RtspStream, mosquitto_broker, needs_rtsp
from test_live import ACROSS, CAMERA, DOOR, FPS, LOOKING, ROOM, SPOT, _frames, _scene, _ScriptedDetector

from ray3d.io.world import read_world
from ray3d.lifting.options import VideoOptions
from ray3d.live.source import FrameSource, SourceGroup
from ray3d.site import Site, Zone
from ray3d.store import read_record

FIXTURES = Path(__file__).parent / "fixtures"


def _live(out: Path, people: np.ndarray, views=(CAMERA,), site: Site = Site((ROOM,), (DOOR,)), store=None,
          mqtt=None, start=None, frame_sleep_s: float = 0.0, file: Path | None = None, **options):
    """A live job over the scene as each camera of ``views`` sees it (every frame processed, faster than the
    clock unless each frame comes ``frame_sleep_s`` after the last: ``start``, a datetime, places its frame 0),
    recorded to ``store`` (default OUT/site.db), published on ``mqtt`` (a URL): its ``jobs.live.LiveRun``.
    ``file``: the one camera's input is this file (a run on a store that recorded it before takes it up where it
    was left)."""
    import itertools

    from ray3d.jobs import CameraChoice, Job
    from ray3d.jobs.live import live_job, local_inputs
    from ray3d.live.runner import LiveOptions

    names = (str(file),) if file else tuple(f"scene from {c.name} ({k + 1})" for k, c in enumerate(views))
    job = Job(names, tuple(CameraChoice(made=c) for c in views), video=VideoOptions(min_track_s=0.5))

    def opened(job, recorder):  # each file taken up where the store's record of it ends
        firsts = [resume.first_index for resume in recorder.resumes]
        sources = [FrameSource(itertools.islice(_frames(len(people), frame_sleep_s, people=people, camera=c), first,
                                                None), FPS, name, waits=True, first_index=first)
                   for c, name, first in zip(views, names, firsts)]
        return local_inputs(job, SourceGroup(sources), list(views), [_ScriptedDetector(people, c) for c in views],
                            recorder.id_prefix, recorder.carried)

    run = live_job(job, out, LiveOptions(page=False, start_time=start, **options), opened, site=site,
                   store=store or out / "site.db", mqtt=mqtt, command="test")
    return run


def _counts(events: list[dict]) -> dict:
    """What a site's counts are made of: entries and exits per zone, crossings per line and direction."""
    counted: dict = {}
    for event in events:
        if event["event"] in ("zone entered", "zone left"):
            key = (event["event"], event["zone"])
        elif event["event"] == "line crossed":
            key = (event["event"], event["line"], event["direction"])
        else:
            continue
        counted[key] = counted.get(key, 0) + 1
    return counted


def _lines(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines()]


def test_a_run_started_again_appends_to_its_outputs_and_the_store_reports_over_both(tmp_path, capsys):
    import datetime

    from ray3d.cli import main

    out, people = tmp_path / "live", _scene()
    recorder = _live(out, people, start=datetime.datetime(2026, 12, 1, 9, 0, 0).astimezone()).recorder
    events = _lines(out / "events.jsonl")
    record = read_record(out / "site.db")
    assert [{k: v for k, v in e.items() if k not in ("at", "run")} for e in record.events] == events
    assert recorder.written["events"] == len(events) and recorder.written["people"] == 2
    assert {e["track"] for e in events} == {"1-0", "1-1"}
    assert len(record.positions["at"]) >= 2 * 3  # each person once a second over 4 s
    world_before = (out / "world.csv").read_text()

    again = _live(out, people, start=datetime.datetime(2026, 12, 1, 9, 1, 0).astimezone()).recorder  # appends
    assert again.run == 2 and again.continues
    both = _lines(out / "events.jsonl")
    assert both[:len(events)] == events and {e["track"] for e in both[len(events):]} == {"2-0", "2-1"}
    assert (out / "world.csv").read_text().startswith(world_before)
    assert set(read_world(out / "world.csv").tracks) == {"1-0", "1-1", "2-0", "2-1"}
    assert (out / "run2" / "site" / "report.html").exists()  # the second run's report beside the first's
    # Each run's report is of its own people, and says so, naming the store's report over every run.
    import csv

    for run, folder in ((1, out / "site"), (2, out / "run2" / "site")):
        with (folder / "tracks.csv").open() as handle:
            assert {row["track"] for row in csv.DictReader(handle)} == {f"{run}-0", f"{run}-1"}
        said = (folder / "README.txt").read_text()
        assert f"covers run {run} of the store {out / 'site.db'} only: its 2 people" in said
        assert f"ray3d site --store {out / 'site.db'} --site SITE" in said
    record = read_record(out / "site.db")
    assert len(record.events) == len(both) and [r["ending"] for r in record.runs] == ["ended", "ended"]
    assert [g["why"] for g in record.gaps] == ["the service was down"]

    site = tmp_path / "site.json"
    site.write_text(json.dumps({"zones": [{"name": "room", "polygon": ROOM.polygon.tolist()}],
                                "lines": [{"name": "door", "start": DOOR.start.tolist(), "end": DOOR.end.tolist()}]}))
    assert main(["site", "--store", str(out / "site.db"), "--site", str(site), "--out", str(tmp_path / "report"),
                 "--every", "1s"]) == 0
    said = capsys.readouterr()
    assert [line for line in said.err.splitlines() if line.startswith("note: camera")]  # the floor its runs decided
    said = said.out
    crossings = _counts(both)
    assert f"line door: {crossings[('line crossed', 'door', 'forward')]} forward, " \
           f"{crossings[('line crossed', 'door', 'back')]} back" in said
    assert "over 2 run(s); 1 gap(s) in the record" in said

    with (tmp_path / "report" / "by-time.csv").open() as handle:
        buckets = list(csv.DictReader(handle))
    assert sum(int(b["door: forward"]) + int(b["door: back"]) for b in buckets) == 4  # two each way, two runs
    assert all(re.fullmatch(r"\d+(\.\d)?", b["room: mean occupancy"]) for b in buckets)  # to 0.1, every one
    assert (tmp_path / "report" / "by-time.png").stat().st_size > 10_000
    if CHROMIUM:  # the page as a browser reads it: no console error
        assert console_errors(tmp_path / "report" / "report.html") == "[]"
    assert main(["site", "--store", str(out / "site.db"), "--site", str(site), "--out", str(tmp_path / "report")]) == 2
    assert "exists" in capsys.readouterr().err  # nothing overwritten
    first_run = record.runs[0]
    assert main(["site", "--store", str(out / "site.db"), "--site", str(site), "--out", str(tmp_path / "period"),
                 "--from", _iso(first_run["first_at"] - 1), "--to", _iso(first_run["last_at"] + 0.05)]) == 0
    assert f"{len(events)} events" in capsys.readouterr().out  # the first run only
    other = tmp_path / "other.json"  # a site the runs did not follow: said, its counts absent
    other.write_text(json.dumps({"zones": [{"name": "hall", "polygon": ROOM.polygon.tolist()}],
                                 "lines": [{"name": "door", "start": DOOR.start.tolist(), "end": DOOR.end.tolist()}]}))
    assert main(["site", "--store", str(out / "site.db"), "--site", str(other), "--out", str(tmp_path / "hall")]) == 0
    said = capsys.readouterr()
    assert ([line for line in said.err.strip().splitlines() if "zone" in line]
            == ["note: zone 'hall': no run of the record followed it; its entries and "
                "exits are not in it (its occupancy and heat map come from the "
                "positions)"])
    assert "zone hall: 0 entries, 0 exits" in said.out


def _iso(at: float) -> str:
    import datetime

    return datetime.datetime.fromtimestamp(at).astimezone().isoformat()


def test_two_cameras_on_one_walk_count_exactly_what_one_camera_counts(tmp_path):
    """The same walk seen twice (as ``vtest.avi`` given twice with its camera): each crossing and each entry is
    one event of one person, exactly as one camera counts them. (Two cameras that see it from different places
    count each crossing once too, ``test_live``; their fused places are better than either camera's, so a
    person walking along a zone's edge may cross it a different number of times.) With several cameras a new
    person is decided after three updates (``LiveFusion``; how many frames that takes depends on the order the
    two views' frames come in): what one camera finds before is not counted then, so both are compared from a
    frame after that moment on."""
    people = _scene()
    _live(tmp_path / "one", people)
    _live(tmp_path / "two", people, views=(CAMERA, CAMERA))
    once, twice = _lines(tmp_path / "one" / "events.jsonl"), _lines(tmp_path / "two" / "events.jsonl")
    decided = max(e["time_s"] for e in twice if e["event"] == "track started")
    assert decided <= min(e["time_s"] for e in once if e["event"] == "track started") + 3 / FPS + 1e-9
    since = decided + 1 / FPS
    counted_once = _counts([e for e in once if e["time_s"] >= since])
    assert counted_once[("line crossed", "door", "forward")] == counted_once[("line crossed", "door", "back")] == 1
    assert _counts([e for e in twice if e["time_s"] >= since]) == counted_once
    assert _counts([e for e in read_record(tmp_path / "two" / "site.db").events if e["time_s"] >= since]) == \
        counted_once
    assert len({e["track"] for e in twice}) == len({e["track"] for e in once}) == 2  # two people, not four


def test_two_cameras_live_events_are_those_of_the_report_on_the_world_file_they_write(tmp_path):
    """One join per live run: the fused world file is joined as the live events joined the cameras' tracks
    (``joined.jsonl``), so its people are the events' people, by name; and the frames are held until who everybody
    is has been decided, so a person's first moments count. The report on that world file finds the live run's
    events: the same kinds, people, places and directions, each within a quarter second (the live positions are
    the causal answers, the world file's the whole tracks'; a track is confirmed live two frames after it began)."""
    from test_live import ACROSS, LOOKING, SPOT

    from ray3d import cameras
    from ray3d.site import Zone

    hall = Zone("hall", np.array([SPOT + a * ACROSS + b * LOOKING for a, b in ((0.6, -3), (4, -3), (4, 3), (0.6, 3))]))
    facing = cameras.h36m("S9", "55011271")
    _live(tmp_path / "two", _scene(), views=(CAMERA, facing), site=Site((hall,), (DOOR,)))
    live, report = _lines(tmp_path / "two" / "events.jsonl"), _lines(tmp_path / "two" / "site" / "events.jsonl")
    joined = [json.loads(line) for line in (tmp_path / "two" / "joined.jsonl").read_text().splitlines()]
    assert sorted(j["person"] for j in joined) == sorted(read_world(tmp_path / "two" / "world.json").tracks)
    assert all(sorted(view for view, _ in j["tracks"]) == [0, 1] for j in joined)  # each seen by both cameras

    def what(event: dict) -> tuple:
        return event["event"], event["track"], event.get("zone") or event.get("line"), event.get("direction")

    assert sorted(map(what, live)) == sorted(map(what, report))
    assert {e["event"] for e in live} >= {"zone left", "zone entered", "line crossed"}
    for event in live:
        assert min(abs(event["time_s"] - e["time_s"]) for e in report if what(e) == what(event)) <= 0.25


def test_a_run_ends_on_purpose_with_until_and_its_outputs_complete(tmp_path):
    people = _scene(400)
    summary = _live(tmp_path / "live", people, until_s=1.0).summary
    assert summary.ending == "until" and summary.processed < len(people)
    record = read_record(tmp_path / "live" / "site.db")
    assert record.runs[0]["ending"] == "until"
    assert len(record.events) == len(_lines(tmp_path / "live" / "events.jsonl")) > 0


def test_a_live_job_that_fails_closes_what_it_opened(tmp_path):
    """``live_job`` owns the clean-up: streams that cannot be opened leave no run in the store (an SQLite store
    holding nothing else is removed) and no thread of the store's or MQTT's; a run refused once its streams are
    open (its event log exists: nothing is written over) is noted in the store as not started, its stream
    closed."""
    from services import free_port

    from ray3d import InputError
    from ray3d.jobs import CameraChoice, Job
    from ray3d.jobs.live import live_job, local_inputs
    from ray3d.live.runner import LiveOptions

    job = Job(("scene",), (CameraChoice(made=CAMERA),), video=VideoOptions(min_track_s=0.5))

    def unopened(job, recorder):
        raise InputError("scene: cannot be opened", ("source",))

    before = set(threading.enumerate())
    with pytest.raises(InputError, match="scene: cannot be opened"):
        live_job(job, tmp_path / "live", LiveOptions(page=False), unopened, store=tmp_path / "live" / "site.db",
                 mqtt=f"mqtt://127.0.0.1:{free_port()}/site")
    assert not (tmp_path / "live" / "site.db").exists()
    assert set(threading.enumerate()) <= before  # the store's committer and MQTT's loop stopped

    out, people = tmp_path / "again", _scene(10)
    out.mkdir()
    (out / "events.jsonl").write_text("")
    source = FrameSource(_frames(len(people), people=people), FPS, "scene", waits=True)
    with pytest.raises(InputError, match="events.jsonl: exists"):
        live_job(job, out, LiveOptions(page=False), lambda job, recorder: local_inputs(
            job, SourceGroup([source]), [CAMERA], [_ScriptedDetector(people)], recorder.id_prefix),
                 store=out / "site.db")
    assert [run["ending"] for run in read_record(out / "site.db").runs] == ["not started"]
    assert source.next() is None  # closed
    assert (out / "events.jsonl").read_text() == ""

    # A failure once the streams are open and before they are followed (here: what the run says as it begins)
    # closes them too, and the signal handlers it set are the caller's again.
    import signal

    source = FrameSource(_frames(len(people), people=people), FPS, "scene", waits=True)
    handlers = {number: signal.getsignal(number) for number in (signal.SIGINT, signal.SIGTERM)}

    def broken(line: str) -> None:
        raise BrokenPipeError("stderr closed")

    with pytest.raises(BrokenPipeError):
        live_job(job, tmp_path / "third", LiveOptions(page=False), lambda job, recorder: local_inputs(
            job, SourceGroup([source]), [CAMERA], [_ScriptedDetector(people)], recorder.id_prefix),
                 store=tmp_path / "third" / "site.db", said=broken, signals=True)
    assert source.next() is None  # closed
    assert set(threading.enumerate()) <= before
    source = FrameSource(_frames(len(people), people=people), FPS, "scene", paced=False)
    run = live_job(job, tmp_path / "fourth", LiveOptions(page=False), lambda job, recorder: local_inputs(
        job, SourceGroup([source]), [CAMERA], [_ScriptedDetector(people)]), signals=True)
    assert run.summary.ending == "ended" and run.signal is None
    assert {number: signal.getsignal(number) for number in handlers} == handlers


def test_events_reach_an_mqtt_broker_in_order_with_the_occupancy_retained_and_home_assistant_discovery(tmp_path):
    import jsonschema
    import paho.mqtt.client as mqtt

    from ray3d.live.mqtt import announcements

    with mosquitto_broker() as port:
        received: list[tuple[str, bytes, bool]] = []
        lock = threading.Lock()

        def subscriber() -> mqtt.Client:
            client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2)
            client.on_message = lambda c, u, message: (lock.acquire(), received.append(
                (message.topic, message.payload, bool(message.retain))), lock.release())
            client.connect("127.0.0.1", port)
            client.subscribe([("site/#", 1), ("homeassistant/#", 1)])
            client.loop_start()
            return client

        listening = subscriber()
        time.sleep(0.5)
        site = Site((ROOM,), (DOOR,))
        publisher = _live(tmp_path / "live", _scene(), site=site, mqtt=f"mqtt://127.0.0.1:{port}/site").mqtt
        time.sleep(1.0)
        listening.loop_stop()
        listening.disconnect()
        events = _lines(tmp_path / "live" / "events.jsonl")
        on_the_bus = [json.loads(payload) for topic, payload, _ in received if topic == "site/event"]
        assert on_the_bus == events and publisher.published == len(events) and publisher.dropped == 0
        # What Home Assistant automates on: each crossing and visit again on its place's topic, with its type.
        on_the_line = [json.loads(payload) for topic, payload, _ in received if topic == "site/line/door/crossing"]
        assert on_the_line == [{"event_type": e["direction"], **e} for e in events if e["event"] == "line crossed"]
        visits = [json.loads(payload) for topic, payload, _ in received if topic == "site/zone/room/event"]
        assert visits == [{"event_type": e["event"].split()[1], **e} for e in events
                          if e["event"] in ("zone entered", "zone left")] and visits
        # a subscriber arriving later reads the state at once: retained
        received.clear()
        late = subscriber()
        time.sleep(1.0)
        late.loop_stop()
        late.disconnect()
        retained = {topic: payload.decode() for topic, payload, kept in received if kept}
        crossings = _counts(events)
        assert retained["site/zone/room/occupancy"] == "0"  # everybody gone at the end
        assert retained["site/line/door/forward"] == str(crossings[("line crossed", "door", "forward")])
        assert retained["site/zone/room/exits"] == str(crossings.get(("zone left", "room"), 0))
        assert retained["site/status"] == "offline"  # the run ended
        announced = {topic: json.loads(payload) for topic, payload in retained.items()
                     if topic.startswith("homeassistant/")}
        # room: occupancy, entries, exits and its events; door: each way and its crossings; the site's falls
        assert announced == dict(announcements(site, "site")) and len(announced) == 10  # and the two health sensors
        for topic, payload in announced.items():
            component = re.fullmatch(r"homeassistant/(sensor|event)/[A-Za-z0-9_-]+/[A-Za-z0-9_-]+/config", topic)[1]
            jsonschema.validate(payload, json.loads((FIXTURES / f"ha_mqtt_{component}.schema.json").read_text()))
            if component == "sensor":
                assert payload["state_topic"] in retained
        assert {p["state_topic"]: p["event_types"] for t, p in announced.items() if "/event/" in t} == {
            "site/line/door/crossing": ["forward", "back"], "site/fall": ["fall"],
            "site/zone/room/event": ["entered", "left", "occupancy_above_limit", "dwell_above_limit"]}


def test_names_become_topics_by_one_rule_and_two_that_would_share_one_are_refused():
    from ray3d import InputError
    from ray3d.live.mqtt import MqttPublisher, topic_name
    from ray3d.site import CountingLine

    assert topic_name("line A (middle)") == "line_A_middle" and topic_name("Caisse n°2") == "Caisse_n_2"
    assert topic_name("east-junction") == "east-junction" and topic_name("(?)") == "unnamed"
    twins = Site((), (CountingLine("line A", DOOR.start, DOOR.end), CountingLine("line_A", DOOR.end, DOOR.start)))
    with pytest.raises(InputError, match=r"mqtt: lines 'line A' and 'line_A' would share the topic "
                                         r"shop/line/line_A; rename one \(argument: site\)"):
        MqttPublisher("mqtt://127.0.0.1:1/shop", twins)


def test_a_broker_that_is_down_never_holds_up_the_stream():
    from services import free_port

    from ray3d.live.mqtt import MqttPublisher
    from ray3d.site.events import SiteMonitor

    site = Site((ROOM,), (DOOR,))
    said: list[str] = []
    publisher = MqttPublisher(f"mqtt://127.0.0.1:{free_port()}/site", site, queue_size=10, report=said.append)
    monitor = SiteMonitor(site, FPS)
    start = time.monotonic()
    for n in range(200):
        publisher.publish([{"event": "track started", "track": str(n), "time_s": n / FPS}], monitor)
    assert time.monotonic() - start < 1.0
    assert publisher.dropped >= 150 and len(said) == 1  # the queue's bound, said once
    publisher.close(wait_s=0.5)


def test_bad_mqtt_urls_are_refused_naming_the_problem():
    from ray3d import InputError
    from ray3d.live.mqtt import parse_mqtt_url

    assert parse_mqtt_url("mqtt://broker.local/shop/floor1") == ("broker.local", 1883, "shop/floor1")
    for url, problem in (("http://x/y", "give mqtt://"), ("mqtt://x:99999/p", "port"), ("mqtt://x/a/+", "+ #")):
        with pytest.raises(InputError, match=re.escape(problem)):
            parse_mqtt_url(url)


class _StandingPerson:
    """A detector that finds one person standing in front of the camera in every frame it is given."""

    layout = "h36m17"
    name = "standing"

    def __init__(self):
        self.pixels = CAMERA.project(_scene(1)[0, 0])

    def prepare(self, frames) -> None:
        pass

    def __call__(self, frame, time_left_s=None):
        from ray3d.video.detectors import Detection

        return [Detection(self.pixels, np.ones(17), 0.9)]


@needs_rtsp
def test_an_rtsp_stream_stopped_and_started_again_three_times_is_followed_on_with_three_gaps(tmp_path, monkeypatch):
    from ray3d.jobs import CameraChoice, Job
    from ray3d.jobs.live import live_job, local_inputs
    from ray3d.live.reconnect import ReconnectingSource
    from ray3d.live.runner import LiveOptions

    monkeypatch.setenv("OPENCV_FFMPEG_CAPTURE_OPTIONS", "rtsp_transport;udp")  # this server has no TCP transport
    stream = RtspStream(CAMERA.image_size, FPS)
    said: list[str] = []
    try:
        stream.start()
        source = None
        for _ in range(40):  # the publisher takes a moment to announce the stream
            try:
                source = ReconnectingSource(stream.url, FPS, stall_s=1.0, backoff_s=0.2, max_backoff_s=1.0,
                                            report=said.append)
                break
            except Exception:
                time.sleep(0.25)
        assert source is not None
        job = Job((stream.url,), (CameraChoice(made=CAMERA),), video=VideoOptions(min_track_s=0.3))
        stop = threading.Event()

        def interrupt() -> None:
            for _ in range(3):
                time.sleep(3.0)
                stream.stop()
                deadline = time.monotonic() + 10  # until the run has seen it go
                while sum("is down" in line for line in said) < len(said) // 2 + 1 and time.monotonic() < deadline:
                    time.sleep(0.1)
                time.sleep(0.5)
                stream.start()
                deadline = time.monotonic() + 20
                while not said[-1:] or "is back" not in said[-1]:
                    if time.monotonic() > deadline:
                        break
                    time.sleep(0.1)
            time.sleep(3.0)
            stop.set()
            source.close()

        threading.Thread(target=interrupt, daemon=True).start()
        summary = live_job(job, tmp_path / "live", LiveOptions(page=False),
                           lambda job, recorder: local_inputs(job, SourceGroup([source]), [CAMERA],
                                                              [_StandingPerson()], recorder.id_prefix),
                           site=Site(), store=tmp_path / "site.db", command="test", stop=stop).summary
    finally:
        stream.close()
    assert summary.ending == "stopped", summary.why
    assert sum("is down" in line for line in said) == 3 and sum("is back" in line for line in said) == 3
    record = read_record(tmp_path / "site.db")
    gaps = [g for g in record.gaps if g["why"] == "the stream was down"]
    assert len(gaps) == 3 and all(g["to_at"] > g["from_at"] for g in gaps)
    started = [e for e in record.events if e["event"] == "track started"]
    ended = [e for e in record.events if e["event"] == "track ended"]
    assert len(started) == 4 and len({e["track"] for e in started}) == 4  # a new person after every gap
    for gap in gaps:  # nobody is followed across a gap: every track lies on one side of it
        for track in {e["track"] for e in started}:
            times = [e["at"] for e in record.events if e["track"] == track]
            assert max(times) <= gap["from_at"] + 0.2 or min(times) >= gap["to_at"] - 0.2
    assert len(ended) == 4


def test_live_writes_no_image_anywhere(tmp_path):
    """Privacy: a live run's outputs, its store and its page hold skeletons and counts, never a frame, a crop or
    an overlay (the report's PNGs are plots drawn from positions)."""
    out = tmp_path / "live"
    _live(out, _scene())
    images = [p for p in out.rglob("*") if p.is_file() and p.read_bytes()[:8] in (b"\x89PNG\r\n\x1a\n",)
              or p.suffix.lower() in (".jpg", ".jpeg", ".mp4", ".avi")]
    assert {p.name for p in images} <= {"floor-plan.png", "occupancy.png"}  # plots, drawn from positions
    import sqlite3

    with sqlite3.connect(out / "site.db") as connection:
        for table, in connection.execute("SELECT name FROM sqlite_master WHERE type = 'table'"):
            for column in connection.execute(f"PRAGMA table_info({table})"):
                assert column[2].upper() != "BLOB"


def test_the_same_live_run_gives_the_same_store_and_report_on_postgresql_as_on_sqlite(tmp_path, capsys):
    """A live run recorded on PostgreSQL, its record copied to SQLite (``ray3d site --copy-to``): the same
    record, and the same report from each."""
    import datetime

    from services import postgresql_server

    from ray3d.cli import main

    start = datetime.datetime(2026, 12, 1, 9, 0, 0).astimezone()
    site = tmp_path / "site.json"
    site.write_text(json.dumps({"zones": [{"name": "room", "polygon": ROOM.polygon.tolist()}],
                                "lines": [{"name": "door", "start": DOOR.start.tolist(), "end": DOOR.end.tolist()}]}))
    lite = tmp_path / "copy.db"
    with postgresql_server() as url:
        _live(tmp_path / "live", _scene(), start=start, store=url)
        assert not (tmp_path / "live" / "site.db").exists()
        assert main(["site", "--store", url, "--copy-to", str(lite), "--site", str(site), "--out",
                     str(tmp_path / "report-postgres"), "--every", "2s"]) == 0
        assert main(["site", "--store", str(lite), "--site", str(site), "--out", str(tmp_path / "report-lite"),
                     "--every", "2s"]) == 0
        on_postgresql, on_sqlite = read_record(url), read_record(lite)
        assert on_postgresql.events == on_sqlite.events and on_postgresql.people == on_sqlite.people
        assert on_postgresql.gaps == on_sqlite.gaps and on_postgresql.runs == on_sqlite.runs
        for key in ("at", "x", "y", "sd_along", "sd_across"):
            np.testing.assert_array_equal(on_postgresql.positions[key], on_sqlite.positions[key])
        assert main(["site", "--store", str(lite), "--copy-to", url, "--site", str(site), "--out",
                     str(tmp_path / "again")]) == 2  # never into a store that holds a record
        assert "holds a record already" in capsys.readouterr().err
    assert len(on_postgresql.events) > 4 and len(on_postgresql.positions["at"]) > 4
    for table in ("places.csv", "events.csv", "people.csv", "gaps.csv", "by-time.csv"):
        assert (tmp_path / "report-lite" / table).read_text() == (tmp_path / "report-postgres" / table).read_text()


def _people_counted(out: Path) -> list[int]:
    """How many people each of a run's tracks had its floor found from (``ankle_plane.people``), in order."""
    return sorted(t.refinement["ankle_plane"]["people"] for t in read_world(out / "world.csv").tracks.values())


def test_a_live_run_starts_on_what_earlier_runs_showed_of_its_cameras_floor_where_the_camera_stands(tmp_path):
    """The store remembers what each camera's people showed of its floor (issue 66): a second run on it lifts its
    first person with the first run's people too; the same camera moved 5 cm (recalibrated) starts afresh, and
    ``ray3d site --store``'s floor is that of the camera as it stands now."""
    from ray3d.store import floor_decisions

    people, store = _scene(), tmp_path / "site.db"
    _live(tmp_path / "first", people, store=store)
    first = _people_counted(tmp_path / "first")
    assert first == list(range(1, len(first) + 1)) and len(first) >= 2
    assert floor_decisions(store)[CAMERA.name].people == len(first)
    _live(tmp_path / "second", people, store=store)
    assert _people_counted(tmp_path / "second") == [n + len(first) for n in first]
    moved = CAMERA.with_origin_at_height(-0.05)  # the same camera's name, its centre 5 cm higher
    _live(tmp_path / "moved", people, views=(moved,), store=store)
    again = _people_counted(tmp_path / "moved")
    assert again == list(range(1, len(again) + 1))
    decided = floor_decisions(store)
    assert list(decided) == [CAMERA.name] and decided[CAMERA.name].people == len(again)
    from ray3d import body  # for the keypoints the store knows the camera's detector gives

    assert decided[CAMERA.name].contact_m == pytest.approx(body.keypoint_source("h36m17").planted_ankle_m)


def test_two_cameras_cross_the_ankles_of_the_people_they_both_see_into_the_floor_they_share(tmp_path):
    """Where the live join decides that two cameras' tracks are one person, their ankle keypoints' rays are
    crossed (``refine.ankle_plane.seen_twice``): the floor itself (the keypoints' planted-ankle height taken off)
    within 2 cm of the scene's, kept in the store under each camera and counted in its decision."""
    import sqlite3

    from ray3d import cameras
    from ray3d.store import floor_decisions

    facing = cameras.h36m("S9", "55011271")
    _live(tmp_path / "two", _scene(), views=(CAMERA, facing))
    joined = (tmp_path / "two" / "joined.jsonl").read_text().splitlines()
    with sqlite3.connect(tmp_path / "two" / "site.db") as connection:
        rows = connection.execute("SELECT camera, height_m, sd_m FROM floor_evidence WHERE kind = 'ankles'").fetchall()
    assert len(rows) == 2 * len(joined) and len(joined) == 2  # each person under each camera
    assert sorted(camera for camera, _, _ in rows) == sorted([CAMERA.name, facing.name] * 2)
    assert all(abs(height) < 0.02 and 0 < sd < 0.1 for _, height, sd in rows)  # about 5 mm off
    decided = floor_decisions(tmp_path / "two" / "site.db")
    assert {camera: plane.seen_twice for camera, plane in decided.items()} == {CAMERA.name: 2, facing.name: 2}


# A zone both people are in around the middle of their walk (the door line lies beside it).
MIDDLE = Zone("middle", np.array([SPOT + a * ACROSS + b * LOOKING for a, b in ((-0.8, -3), (0.3, -3), (0.3, 3),
                                                                               (-0.8, 3))]))
KILLED_LIVE = """
import sys
from pathlib import Path
sys.path.insert(0, sys.argv[1])
from test_live_site import MIDDLE, _live
from test_live import DOOR, ROOM, _scene
from ray3d.site import Site
_live(Path(sys.argv[2]), _scene(), site=Site((ROOM, MIDDLE), (DOOR,)), mqtt=sys.argv[3], frame_sleep_s=0.2)
"""


def _gliding_scene() -> np.ndarray:
    """``_scene``'s two people with their feet on the floor throughout: each one's first pose carried along their
    walk (the bundled clip is a jump: a kill in mid-air leaves a carried place a metre or two off along the ray, as
    any floor point of feet off the floor is)."""
    people = _scene()
    return people[:1] + (people[:, :, :1] - people[:1, :, :1]) * [1.0, 1.0, 0.0]


KILLED_ON_A_FILE = KILLED_LIVE.replace("frame_sleep_s=0.2)", "frame_sleep_s=0.2, file=Path(sys.argv[4]))") \
    .replace("from test_live_site import MIDDLE, _live", "from test_live_site import MIDDLE, _gliding_scene, _live") \
    .replace("_live(Path(sys.argv[2]), _scene(),", "_live(Path(sys.argv[2]), _gliding_scene(),")


def _kill_when_in_the_middle(out: Path, url: str, tmp_path: Path, *arguments: str) -> None:
    """``KILLED_LIVE`` (or a variant taking ``arguments``) killed outright once a crossing is counted and somebody
    is in the middle zone, the store's commit of it made."""
    import signal
    import subprocess
    import sys

    script = KILLED_ON_A_FILE if arguments else KILLED_LIVE
    with (tmp_path / "stderr").open("w") as stderr:
        first = subprocess.Popen([sys.executable, "-c", script, str(Path(__file__).parent), str(out), url, *arguments],
                                 stdout=subprocess.DEVNULL, stderr=stderr)
    try:
        deadline = time.monotonic() + 300
        while True:  # until a crossing is counted and somebody is in the middle zone
            assert first.poll() is None and time.monotonic() < deadline, (tmp_path / "stderr").read_text()
            events = _whole_lines(out / "events.jsonl")
            inside = _counts([e for e in events if e.get("zone") == "middle"])
            if any(e["event"] == "line crossed" for e in events) and \
                    inside.get(("zone entered", "middle"), 0) > inside.get(("zone left", "middle"), 0):
                break
            time.sleep(0.05)
        time.sleep(0.6)  # the store's commit of it
        first.send_signal(signal.SIGKILL)
    finally:
        first.kill()
        first.wait()


def _whole_lines(path: Path) -> list[dict]:
    """The events of a log being written: its whole lines."""
    text = path.read_text() if path.exists() else ""
    return [json.loads(line) for line in text[:text.rfind("\n") + 1].splitlines()]


def test_a_live_run_killed_outright_is_closed_by_its_restart_and_its_mqtt_counts_go_on(tmp_path):
    """SIGKILL while two people are in view, one in a zone, after a crossing; the same run again: every "track
    started" in the store has its "track ended" (the killed run's people ended at its last commit, "the service
    stopped", their visits left), in the store and events.jsonl; the counts on MQTT go on from the store's."""
    import paho.mqtt.client as mqtt


    out, site = tmp_path / "live", Site((ROOM, MIDDLE), (DOOR,))
    with mosquitto_broker() as port:
        url = f"mqtt://127.0.0.1:{port}/site"
        _kill_when_in_the_middle(out, url, tmp_path)
        logged = _whole_lines(out / "events.jsonl")
        before = read_record(out / "site.db")
        started = {e["track"] for e in before.events if e["event"] == "track started"}
        open_tracks = started - {e["track"] for e in before.events if e["event"] == "track ended"}
        open_visits = {(e["track"], e["zone"]) for e in before.events if e["event"] == "zone entered"} - \
            {(e["track"], e["zone"]) for e in before.events if e["event"] == "zone left"}
        assert open_tracks == {"1-0", "1-1"} and ("middle" in {zone for _, zone in open_visits})

        recorder = _live(out, _scene(), site=site, mqtt=url).recorder  # the service restarted
        closed = recorder.closed
        assert {e["track"] for e in closed if e["event"] == "track ended"} == open_tracks
        assert {(e["track"], e["zone"]) for e in closed if e["event"] == "zone left"} == open_visits
        assert all(e["reason"] == "the service stopped" for e in closed)
        record = read_record(out / "site.db")
        ends = [e["track"] for e in record.events if e["event"] == "track ended"]
        assert sorted(ends) == sorted(e["track"] for e in record.events if e["event"] == "track started")
        assert {"2-0", "2-1"} <= set(ends) and [r["ending"] for r in record.runs] == ["cut off", "ended"]
        # events.jsonl: what the killed run wrote, then what closed it, then the new run's
        after = _lines(out / "events.jsonl")
        assert after[:len(logged)] == logged and after[len(logged):len(logged) + len(closed)] == closed
        assert {e["track"][:2] for e in after[len(logged) + len(closed):]} == {"2-"}

        # MQTT: the counts over both runs, as the store's report counts them, not the second run's alone
        received: dict[str, str] = {}
        late = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2)
        late.on_message = lambda c, u, message: received.update({message.topic: message.payload.decode()})
        late.connect("127.0.0.1", port)
        late.subscribe("site/#", 1)
        late.loop_start()
        time.sleep(1.0)
        late.loop_stop()
        late.disconnect()
    counted, second = _counts(record.events), _counts([e for e in record.events if e["run"] == 2])
    for direction in ("forward", "back"):
        assert received[f"site/line/door/{direction}"] == str(counted.get(("line crossed", "door", direction), 0))
    assert sum(n for key, n in counted.items() if key[0] == "line crossed") > \
        sum(n for key, n in second.items() if key[0] == "line crossed")  # the killed run's crossings go on counting
    for zone in ("middle", "room"):
        assert received[f"site/zone/{zone}/entries"] == str(counted.get(("zone entered", zone), 0))
        assert received[f"site/zone/{zone}/exits"] == str(counted.get(("zone left", zone), 0))
    assert received["site/zone/middle/exits"] != str(second.get(("zone left", "middle"), 0))


def test_the_people_in_view_when_a_run_on_a_file_is_killed_keep_their_ids_and_are_not_counted_again(tmp_path):
    """Issue 67, item 3: SIGKILL while two people are in view of a file being followed, one in a zone, after a
    crossing; the same run again takes the file up where the store left it and its tracker gives the two the ids
    they had: no track started again, their visits go on (no second entry; their exits counted once), and the
    store holds what an uninterrupted run holds (the same counts, tracks and people), no event twice."""
    import sqlite3


    site, clip = Site((ROOM, MIDDLE), (DOOR,)), tmp_path / "clip.avi"
    clip.write_bytes(b"")  # a file input: taken up where it was left
    _live(tmp_path / "whole", _gliding_scene(), site=site, file=clip)
    whole = read_record(tmp_path / "whole" / "site.db")
    out = tmp_path / "live"
    with mosquitto_broker() as port:
        url = f"mqtt://127.0.0.1:{port}/site"
        _kill_when_in_the_middle(out, url, tmp_path, str(clip))
        before = read_record(out / "site.db")
        open_tracks = {e["track"] for e in before.events if e["event"] == "track started"} - \
            {e["track"] for e in before.events if e["event"] == "track ended"}
        assert open_tracks == {"1-0", "1-1"}
        recorder = _live(out, _gliding_scene(), site=site, mqtt=url, file=clip).recorder
    assert recorder.closed == [] and {p.person for p in recorder.carried} == open_tracks
    assert recorder.resumes[0].first_index > 0  # taken up, not begun again
    record = read_record(out / "site.db")
    second = [e for e in record.events if e["run"] == 2]
    assert not [e for e in second if e["event"] == "track started"]  # the two go on, nobody new
    assert {e["track"] for e in second} == open_tracks and not [e for e in record.events if "reason" in e]
    started = [e["track"] for e in record.events if e["event"] == "track started"]
    assert sorted(started) == sorted(e["track"] for e in record.events if e["event"] == "track ended")
    assert _counts(record.events) == _counts(whole.events)
    assert len(started) == len([e for e in whole.events if e["event"] == "track started"])
    assert {p["person"] for p in record.people} == open_tracks
    keys = [(e["event"], e["track"], e["time_s"], e.get("zone"), e.get("line")) for e in record.events]
    assert len(keys) == len(set(keys))  # no event twice
    with sqlite3.connect(out / "site.db") as connection:
        assert connection.execute("SELECT COUNT(*) FROM carried").fetchone() == (0,)  # every carried track ended


class _SlowFor:
    """A detector slower than the stream (``slow_s`` a frame) over frames ``first`` to ``last`` (excluded)."""

    def __init__(self, detector: _ScriptedDetector, first: int, last: int, slow_s: float):
        self.detector, self.first, self.last, self.slow_s = detector, first, last, slow_s
        self.layout, self.name = detector.layout, "slow"

    def prepare(self, frames) -> None:
        pass

    def __call__(self, frame, time_left_s=None):
        index = int(frame[0, 0, 0]) + 256 * int(frame[0, 0, 1])
        if self.first <= index < self.last:
            time.sleep(self.slow_s)
        return self.detector(frame, time_left_s)


def _paced_live(out: Path, people: np.ndarray, detector, site: Site, mqtt=None, started=lambda url: None,
                **options):
    """A live job over the scene played at its rate (frames dropped when ``detector`` cannot keep up), recorded to
    OUT/site.db."""
    from ray3d.jobs import CameraChoice, Job
    from ray3d.jobs.live import live_job, local_inputs
    from ray3d.live.runner import LiveOptions

    job = Job(("scene",), (CameraChoice(made=CAMERA),), video=VideoOptions(min_track_s=0.5))
    job.lifter("h36m17").prepare_small_batches()  # before the stream starts: frames meanwhile would be dropped

    def opened(job, recorder):
        source = FrameSource(_frames(len(people), people=people), FPS, "scene", paced=True)
        return local_inputs(job, SourceGroup([source]), [CAMERA], [detector], recorder.id_prefix)

    return live_job(job, out, LiveOptions(**{"page": False, **options}), opened, site=site, store=out / "site.db",
                    mqtt=mqtt, command="test", started=started).summary


def test_a_run_that_cannot_keep_up_says_so_on_stderr_the_page_mqtt_and_in_the_store_and_its_report(tmp_path,
                                                                                                     capsys):
    """Issue 68, item 1: a detector six times slower than the stream over frames 15-35 drops many of them, even
    taking one frame in four (as many as a camera skips to keep up, ``live.people.MOST_FRAMES_APART``); the
    stretch is said on stderr as it begins and ends, shown in /state, published on MQTT (announced to Home
    Assistant) and recorded in the store, whose report marks it uncertain. The tracker and the site's rules are
    given each processed frame's own number (the real interval between them)."""
    import contextlib
    import csv
    import urllib.request

    import jsonschema
    import paho.mqtt.client as mqtt

    from ray3d.site.record import analyse_record

    people, site = _scene(70), Site((ROOM,), (DOOR,))
    detector = _ScriptedDetector(people)
    states: list[dict] = []
    done = threading.Event()

    def started(url: str) -> None:
        def poll() -> None:
            while not done.is_set():
                with contextlib.suppress(OSError, ValueError):  # the page not up yet, or going
                    states.append(json.loads(urllib.request.urlopen(f"{url}state", timeout=2).read()))
                time.sleep(0.1)

        threading.Thread(target=poll, daemon=True).start()

    with mosquitto_broker() as port:
        received: list[tuple[str, str]] = []
        listening = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2)
        listening.on_message = lambda c, u, message: received.append((message.topic, message.payload.decode()))
        listening.connect("127.0.0.1", port)
        listening.subscribe([("site/health/#", 1), ("homeassistant/sensor/site/health/config", 1)])
        listening.loop_start()
        time.sleep(0.5)
        summary = _paced_live(tmp_path / "live", people, _SlowFor(detector, 15, 35, 0.6), site,
                              mqtt=f"mqtt://127.0.0.1:{port}/site", started=started,
                              page=True, port=0, behind_window_s=1.0)
        done.set()
        time.sleep(1.0)
        listening.loop_stop()
        listening.disconnect()
    err = capsys.readouterr().err
    assert summary.dropped >= 10
    # The tracker and the rules were given the frames' own numbers: gaps where frames were dropped.
    seen = sorted(set(detector.calls))
    assert any(b - a > 1 for a, b in zip(seen, seen[1:])) and seen[-1] == len(people) - 1
    # stderr: its start and its end
    assert re.search(r"camera h36m:S9:54138969: falling behind: \d+ % of frames dropped and [\d.]+ people a frame "
                     r"left for the next over the last 1 s; counts from now on are uncertain", err)
    assert re.search(r"keeping up again after \d+ s falling behind \(\d+ % of its frames dropped, \d+ people left for "
                     r"the next frame, from [\d.]+ s to [\d.]+ s of the stream\); counts in that time are uncertain",
                     err)
    # The slow stretch, where the most frames were dropped; a busy machine may add a short hiccup of its own (two or
    # three frames), said the same way, and one just before the slow frames may run into their stretch.
    stretch = max(summary.behind, key=lambda s: s.dropped)
    assert 0.5 < stretch.from_s < 2.5 and 2.5 < stretch.to_s < 6.9 and stretch.share > 0.3  # frames 15-35
    assert all(s.dropped <= 3 for s in summary.behind if s is not stretch)
    # the page's state: a warning while it lasted, the stretch kept after
    states = [s for s in states if "health" in s]  # those before the first frame have none
    assert any(s["health"]["falling_behind"] for s in states)
    assert not states[-1]["health"]["falling_behind"]
    assert len(states[-1]["health"]["stretches"]) == len(summary.behind)
    # MQTT: the health sensor announced, falling behind then keeping up, retained
    config = json.loads(next(p for t, p in received if t == "homeassistant/sensor/site/health/config"))
    jsonschema.validate(config, json.loads((FIXTURES / "ha_mqtt_sensor.schema.json").read_text()))
    assert config["state_topic"] == "site/health/state"
    said = [p for t, p in received if t == "site/health/state"]
    assert "falling behind" in said and said[-1] == "keeping up"
    assert max(int(p) for t, p in received if t == "site/health/dropped_percent") > 30
    # the store: one row, read back; the report marks the stretch uncertain
    record = read_record(tmp_path / "live" / "site.db")
    assert len(record.behind) == len(summary.behind)
    row = record.behind[summary.behind.index(stretch)]
    assert row["to_at"] - row["from_at"] == pytest.approx(stretch.to_s - stretch.from_s, abs=0.01)
    assert row["dropped_share"] == pytest.approx(stretch.share)
    analyse_record(record, site, tmp_path / "report", every_s=1.0)
    buckets = (tmp_path / "report" / "by-time.csv").read_text()
    assert "uncertain %" in buckets.splitlines()[0]
    uncertain = [int(r["uncertain %"]) for r in csv.DictReader(buckets.splitlines())]
    first = next(i for i, u in enumerate(uncertain) if u > 0)
    assert 0 in uncertain[first:]  # after it: certain again
    assert "Counts uncertain from" in (tmp_path / "report" / "report.html").read_text()


def test_a_run_that_keeps_up_says_nothing_of_falling_behind(tmp_path, capsys):
    people, site = _scene(50), Site((ROOM,), (DOOR,))
    summary = _paced_live(tmp_path / "live", people, _ScriptedDetector(people), site)
    assert summary.behind == [] and "falling behind" not in capsys.readouterr().err
    assert read_record(tmp_path / "live" / "site.db").behind == []
