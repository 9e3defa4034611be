"""A site that runs for months: a live run records to its store, and one started again on the same output appends
(nothing overwritten, ids apart, the gap between them recorded) and ``ray3d site --store`` reports over both; two
cameras on one walk count exactly what one counts; a stream served over RTSP that goes down three times is
reopened three times, each gap recorded, nobody counted across one; events on MQTT, in order, the occupancy
retained and the zones and lines announced to Home Assistant; --until; and no image anywhere."""

from __future__ import annotations

import json
import re
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from ray3d.io.world import read_world
from ray3d.lifting.options import VideoOptions
from ray3d.live.source import FrameSource, SourceGroup
from ray3d.site import Site
from ray3d.store import RunRecorder, read_record

from browser import CHROMIUM, console_errors
from services import RtspStream, mosquitto_broker, needs_rtsp
from test_live import CAMERA, DOOR, FPS, ROOM, _frames, _scene, _ScriptedDetector

FIXTURES = Path(__file__).parent / "fixtures"


def _live(out: Path, people: np.ndarray, views=(CAMERA,), site: Site = Site((ROOM,), (DOOR,)), store=None,
          mqtt=None, start=None, **options):
    """A live job over the scene as each camera of ``views`` sees it (every frame processed, faster than the
    clock: ``start``, a datetime, places its frame 0), recorded to ``store`` (default OUT/site.db): its summary
    and its recorder."""
    from ray3d.jobs import CameraChoice, Job
    from ray3d.jobs.live import local_inputs, run_live_job, start_record
    from ray3d.live.runner import LiveOptions

    names = tuple(f"scene from {c.name} ({k + 1})" for k, c in enumerate(views))
    job = Job(names, tuple(CameraChoice(made=c) for c in views), video=VideoOptions(min_track_s=0.5))
    recorder = start_record(job, store or out / "site.db", "test", site, start)
    sources = [FrameSource(_frames(len(people), people=people, camera=c), FPS, name, waits=True)
               for c, name in zip(views, names)]
    inputs = local_inputs(job, SourceGroup(sources), list(views), [_ScriptedDetector(people, c) for c in views],
                          recorder.id_prefix)
    summary = run_live_job(job, inputs, out, site, LiveOptions(page=False, **options), recorder=recorder,
                           mqtt=mqtt)
    return summary, recorder


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
    from ray3d.cli import main

    import datetime

    out, people = tmp_path / "live", _scene()
    first, recorder = _live(out, people, start=datetime.datetime(2026, 12, 1, 9, 0, 0).astimezone())
    events = _lines(out / "events.jsonl")
    record = read_record(out / "site.db")
    assert [{k: v for k, v in e.items() if k not in ("at", "run")} for e in record.events] == events
    assert recorder.written["events"] == len(events) and recorder.written["people"] == 2
    assert {e["track"] for e in events} == {"1-0", "1-1"}
    assert len(record.positions["at"]) >= 2 * 3  # each person once a second over 4 s
    world_before = (out / "world.csv").read_text()

    second, again = _live(out, people, start=datetime.datetime(2026, 12, 1, 9, 1, 0).astimezone())  # appends
    assert again.run == 2 and again.continues
    both = _lines(out / "events.jsonl")
    assert both[:len(events)] == events and {e["track"] for e in both[len(events):]} == {"2-0", "2-1"}
    assert (out / "world.csv").read_text().startswith(world_before)
    assert set(read_world(out / "world.csv").tracks) == {"1-0", "1-1", "2-0", "2-1"}
    assert (out / "run2" / "site" / "report.html").exists()  # the second run's report beside the first's
    record = read_record(out / "site.db")
    assert len(record.events) == len(both) and [r["ending"] for r in record.runs] == ["ended", "ended"]
    assert [g["why"] for g in record.gaps] == ["the service was down"]

    site = tmp_path / "site.json"
    site.write_text(json.dumps({"zones": [{"name": "room", "polygon": ROOM.polygon.tolist()}],
                                "lines": [{"name": "door", "start": DOOR.start.tolist(), "end": DOOR.end.tolist()}]}))
    assert main(["site", "--store", str(out / "site.db"), "--site", str(site), "--out", str(tmp_path / "report"),
                 "--every", "1s"]) == 0
    said = capsys.readouterr().out
    crossings = _counts(both)
    assert f"line door: {crossings[('line crossed', 'door', 'forward')]} forward, " \
           f"{crossings[('line crossed', 'door', 'back')]} back" in said
    assert "over 2 run(s); 1 gap(s) in the record" in said
    import csv

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
    assert said.err.strip().splitlines() == ["note: zone 'hall': no run of the record followed it; its entries and "
                                             "exits are not in it (its occupancy and heat map come from the "
                                             "positions)"]
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
    from ray3d import cameras
    from ray3d.site import Zone
    from test_live import ACROSS, LOOKING, SPOT

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
    summary, recorder = _live(tmp_path / "live", people, until_s=1.0)
    assert summary.ending == "until" and summary.processed < len(people)
    record = read_record(tmp_path / "live" / "site.db")
    assert record.runs[0]["ending"] == "until"
    assert len(record.events) == len(_lines(tmp_path / "live" / "events.jsonl")) > 0


def test_events_reach_an_mqtt_broker_in_order_with_the_occupancy_retained_and_home_assistant_discovery(tmp_path):
    import jsonschema
    import paho.mqtt.client as mqtt

    from ray3d.live.mqtt import MqttPublisher, sensors

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
        publisher = MqttPublisher(f"mqtt://127.0.0.1:{port}/site", site)
        _live(tmp_path / "live", _scene(), site=site, mqtt=publisher)
        time.sleep(1.0)
        listening.loop_stop()
        listening.disconnect()
        events = _lines(tmp_path / "live" / "events.jsonl")
        on_the_bus = [json.loads(payload) for topic, payload, _ in received if topic == "site/event"]
        assert on_the_bus == events and publisher.published == len(events) and publisher.dropped == 0
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
        assert retained["site/status"] == "offline"  # the run ended
        schema = json.loads((FIXTURES / "ha_mqtt_sensor.schema.json").read_text())
        announced = {topic: json.loads(payload) for topic, payload in retained.items()
                     if topic.startswith("homeassistant/")}
        assert announced == dict(sensors(site, "site")) and len(announced) == 4
        for topic, payload in announced.items():
            assert re.fullmatch(r"homeassistant/sensor/[A-Za-z0-9_-]+/[A-Za-z0-9_-]+/config", topic)
            jsonschema.validate(payload, schema)
            assert payload["state_topic"] in retained


def test_a_broker_that_is_down_never_holds_up_the_stream():
    from ray3d.live.mqtt import MqttPublisher
    from ray3d.site.events import SiteMonitor
    from services import free_port

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
    from ray3d.jobs.live import local_inputs, run_live_job
    from ray3d.live.runner import LiveOptions
    from ray3d.live.reconnect import ReconnectingSource

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
        recorder = RunRecorder(tmp_path / "site.db", "test", [stream.url], [False])
        inputs = local_inputs(job, SourceGroup([source]), [CAMERA], [_StandingPerson()], recorder.id_prefix)
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
        summary = run_live_job(job, inputs, tmp_path / "live", Site(), LiveOptions(page=False), stop=stop,
                               recorder=recorder)
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

    from ray3d.cli import main
    from services import postgresql_server

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
