"""Sites: the site file and its refusals, line crossings with their direction and time, zone visits and their
dwell (a track's time in a zone, the monitor's), who is in a zone (one rule), and every event of a world's tracks
in time order."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from browser import console_errors, needs_chromium, screenshot
from hypothesis import given, settings
from hypothesis import strategies as st

from ray3d import InputError, cameras
from ray3d.io.world import LiftResult, World
from ray3d.site import CountingLine, Site, Zone, in_zones, line_crossings, site_events
from ray3d.site.events import replay_site
from ray3d.site.files import read_site

DOOR = CountingLine("door", np.array([0.0, -1.0]), np.array([0.0, 1.0]))  # along +y: its left is -x
ROOM = Zone("room", np.array([[1.0, -2.0], [4.0, -2.0], [4.0, 2.0], [1.0, 2.0]]))


def _walk(xs, fps=10.0):
    """(T,) seconds and (T, 2) points walking along y = 0 through the given x positions, one per frame."""
    xs = np.asarray(xs, dtype=np.float64)
    return np.arange(len(xs)) / fps, np.column_stack([xs, np.zeros_like(xs)])


def test_a_walk_through_the_door_both_ways_crosses_it_once_each_way_at_the_right_time():
    times, points = _walk(np.concatenate([np.linspace(-2, 2, 41), np.linspace(2, -2, 41)[1:]]))
    crossings = line_crossings(times, points, DOOR)
    assert [c["direction"] for c in crossings] == ["forward", "back"]  # left (-x) to right (+x), then back
    assert crossings[0]["time_s"] == pytest.approx(2.0) and crossings[1]["time_s"] == pytest.approx(6.0)
    assert crossings[0]["place_m"] == [0.0, 0.0] and crossings[0]["sides_m"][0] > 0 >= crossings[0]["sides_m"][1]


def test_passing_beside_the_line_is_not_crossing_it():
    times, points = _walk(np.linspace(-2, 2, 41))
    assert line_crossings(times, points + [0.0, 1.5], DOOR) == []


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-3, 3, allow_nan=False), min_size=2, max_size=40))
def test_reversing_time_swaps_every_direction(xs):
    times, points = _walk(xs)
    forward = line_crossings(times, points, DOOR)
    backward = line_crossings(times, points[::-1], DOOR)
    assert [c["direction"] for c in backward] == [
        {"forward": "back", "back": "forward"}[c["direction"]] for c in forward[::-1]]


def _world_of(paths: dict, fps: float = 10.0) -> World:
    """A world of tracks walking the (T, 2) floor ``paths`` ({track: points}), one frame each from frame 0."""
    def result(points):
        joints = np.zeros((len(points), 17, 3))
        joints[:, :, :2] = np.asarray(points, dtype=np.float64)[:, None]
        return LiftResult(joints, np.zeros((len(points), 17), bool), fps, np.arange(len(points)))

    return World({track: result(points) for track, points in paths.items()}, cameras.h36m("S9", "54138969"), "test")


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.floats(1.1, 3.9), st.floats(-1.9, 1.9)), min_size=1, max_size=30))
def test_a_track_that_never_leaves_a_zone_never_enters_or_leaves_it_and_spends_its_whole_time_there(inside):
    replay = replay_site(_world_of({"1": np.array(inside)}), Site((ROOM,), ()))
    assert not [e for e in replay.events if e["event"] in ("zone entered", "zone left")]
    assert replay.time_in_zones == {"1": {"room": pytest.approx((len(inside) - 1) / 10.0)}}
    assert replay.occupancy["room"].tolist() == [1] * len(inside)


def test_a_visit_has_its_entry_exit_and_dwell():
    _, points = _walk(np.linspace(0, 5, 51))  # in the room for x in [1, 4]: from 1 s to 4 s
    replay = replay_site(_world_of({"1": points}), Site((ROOM,), ()))
    (entered,) = [e for e in replay.events if e["event"] == "zone entered"]
    (left,) = [e for e in replay.events if e["event"] == "zone left"]
    assert entered["time_s"] == pytest.approx(1.0) and left["time_s"] == pytest.approx(4.1)
    assert left["dwell_s"] == pytest.approx(3.1)  # from the first frame inside to the first outside
    assert replay.time_in_zones["1"]["room"] == pytest.approx(3.1)


def test_a_tracks_time_in_a_zone_in_tracks_csv_is_the_monitors_dwell_with_the_visit_open_at_its_end(tmp_path):
    """tracks.csv's time in a zone is the site monitor's (one rule, issue 69): the dwell of the visits that left
    plus the visit under way when the track ended (the monitor's ``time_in_zones``, asked live before ``ended``),
    which no "zone left" reports; a track that starts inside counts from its first frame."""
    import csv

    from ray3d.site import SiteMonitor
    from ray3d.site.report import analyse_site

    _, through_and_back = _walk(np.concatenate([np.linspace(0, 5, 51), np.linspace(5, 2.5, 26)[1:]]))
    _, starts_inside = _walk(np.linspace(2, 6, 41))
    paths = {"through, then back in and ended there": through_and_back, "starts inside": starts_inside,
             "never in": through_and_back + [0.0, 5.0]}
    world, site = _world_of(paths), Site((ROOM,), ())
    events, _, _ = analyse_site(world, site, tmp_path / "report")
    with (tmp_path / "report" / "tracks.csv").open() as handle:
        tables = {row["track"]: float(row["time_in_room_s"]) for row in csv.DictReader(handle)}
    live = SiteMonitor(site, 10.0)
    for frame in range(max(len(points) for points in paths.values())):
        live.update(frame, {track: world.tracks[track].joints[frame] for track, points in paths.items()
                            if frame < len(points)})
        for track in [t for t, points in paths.items() if len(points) == frame + 1]:
            assert live.time_in_zones(track)["room"] == pytest.approx(tables[track], abs=5e-4)
            live.ended(track)
    for track, points in paths.items():  # from the events: the visits that left, and the one open at the end
        mine = [e for e in events if e["track"] == track]
        left = [e["dwell_s"] for e in mine if e["event"] == "zone left"]
        entered = [e["time_s"] for e in mine if e["event"] == "zone entered"]
        (ended,) = [e["time_s"] for e in mine if e["event"] == "track ended"]
        # The visit under way at the end began at its last entry, or at the track's start (frame 0) if it had none.
        still_in = ended - (entered[-1] if len(entered) > len(left) else 0.0) if ROOM.contains(points[-1]) else 0.0
        assert tables[track] == pytest.approx(sum(left) + still_in, abs=1e-3), track
    assert tables == pytest.approx({"through, then back in and ended there": 3.1 + 1.5, "starts inside": 2.1,
                                    "never in": 0.0}, abs=1e-3)


def test_who_is_in_a_zone_is_one_rule_for_the_monitor_and_the_stores_record():
    """``in_zones`` decides who is in a zone: the monitor's occupants (and so its entries and exits) are those
    whose latest place it puts inside, and the store's record counts the same from its positions (issue 69)."""
    from ray3d.site import SiteMonitor

    places = np.array([[2.0, 0.0], [0.0, 0.0], [3.9, 1.9], [4.1, 0.0]])
    assert in_zones(Site((ROOM,), ()), places)["room"].tolist() == [True, False, True, False]
    assert in_zones(Site((ROOM,), ()), np.zeros((0, 2)))["room"].tolist() == []
    monitor = SiteMonitor(Site((ROOM,), ()), 10.0)
    people = {str(k): np.zeros((17, 3)) + [*p, 0.0] for k, p in enumerate(places)}
    monitor.update(0, people)
    assert monitor.occupants == {"room": {"0", "2"}}
    people["1"] = people["1"] + [2.0, 0.0, 0.0]  # walks in
    monitor.update(1, people)
    assert monitor.occupants == {"room": {"0", "1", "2"}}
    monitor.ended("0")
    assert monitor.occupants == {"room": {"1", "2"}}


def test_a_track_is_announced_once_followed_long_enough_or_at_its_first_other_event():
    """Live (``announced_after_s``, the job's shortest track): a track followed for a moment and gone says nothing;
    one followed long enough is "track started" at its first frame, handed over when it has lasted that long; one
    that crosses a line or enters a zone first is announced with it, before it; a person carried across a restart
    was announced by the run before."""
    from ray3d.site import SiteMonitor
    from ray3d.site.events import CarriedPerson

    def standing(x: float) -> np.ndarray:
        return np.zeros((17, 3)) + [x, 0.0, 0.0]

    monitor = SiteMonitor(Site((ROOM,), (DOOR,)), 10.0, announced_after_s=1.0)
    said: dict[int, list] = {}
    for frame in range(30):
        people = {"long": standing(-3.0)}
        if frame < 6:
            people["moment"] = standing(2.0)  # 0.6 s in the room from its first frame, never announced
            assert monitor.occupants == {"room": set()} or frame == 0  # nobody in the room meanwhile
        if 10 <= frame < 14:
            people["walks in"] = standing(-0.5 + (frame - 10) * 0.6)  # crosses the door at its 2nd frame
        said[frame] = monitor.update(frame, people)
        if frame == 5:
            assert monitor.ended("moment") == []
        if frame == 13:
            said[frame] += monitor.ended("walks in")
    named = {f: [(e["event"], e["track"], round(e["time_s"], 2)) for e in events]
             for f, events in said.items() if events}
    assert named == {9: [("track started", "long", 0.0)],
                     11: [("track started", "walks in", 1.0), ("line crossed", "walks in", 1.08)],
                     13: [("zone entered", "walks in", 1.3), ("track ended", "walks in", 1.3)]}
    assert monitor.ended("long")[-1]["event"] == "track ended"
    at_once = SiteMonitor(Site((ROOM,), ()), 10.0)  # a finished world's tracks: announced at their first frame
    assert [e["event"] for e in at_once.update(0, {"a": standing(-3.0)})] == ["track started"]
    assert [e["event"] for e in at_once.ended("a")] == ["track ended"]
    carried = SiteMonitor(Site((ROOM,), ()), 10.0, [CarriedPerson("1-4", (-3.0, 0.0), 4.0, 4.2, {}, {})], 1.0)
    assert carried.update(43, {"1-4": standing(-3.0)}) == []
    assert [e["event"] for e in carried.ended("1-4")] == ["track ended"]


def test_every_event_of_a_world_in_time_order_with_its_evidence():
    times, points = _walk(np.linspace(-2, 5, 71))
    joints = np.zeros((len(points), 17, 3))
    joints[:, :, :2] = points[:, None]
    joints[:, :, 2] = 0.9
    result = LiftResult(joints, np.zeros((len(points), 17), bool), 10.0, np.arange(100, 100 + len(points)))
    world = World({"7": result}, cameras.h36m("S9", "54138969"), "ray3d")
    events = site_events(world, Site((ROOM,), (DOOR,)))
    assert [e["event"] for e in events] == ["track started", "line crossed", "zone entered", "zone left",
                                            "track ended"]
    crossed, entered, left = events[1:4]
    assert crossed["track"] == "7" and crossed["time_s"] == pytest.approx(12.0) and crossed["frames"] == [119, 120]
    assert entered["time_s"] == pytest.approx(13.0) and entered["frames"] == [129, 130]
    assert left["dwell_s"] == pytest.approx(3.1) and left["place_m"][0] > 4.0


def test_a_site_file_reads_zones_and_lines(tmp_path):
    path = tmp_path / "site.json"
    path.write_text(json.dumps({"zones": [{"name": "room", "polygon": ROOM.polygon.tolist()}],
                                "lines": [{"name": "door", "start": [0, -1], "end": [0, 1]}]}))
    site = read_site(path)
    assert [z.name for z in site.zones] == ["room"] and site.lines[0].end.tolist() == [0.0, 1.0]


@pytest.mark.parametrize("document, message", [
    ([], "expected an object with zones and / or lines"),
    ({"zones": []}, None),
    ({"zones": [], "doors": []}, "unknown field 'doors'"),
    ({"zones": {}}, "zones: expected a list"),
    ({"zones": [{"name": "a"}]}, r"zones\[0\]: expected the fields name, polygon"),
    ({"zones": [{"name": "a", "polygon": [[0, 0], [1, 0], [1, 1]], "max_occupancy": 1.5}]}, "positive whole number"),
    ({"zones": [{"name": "a", "polygon": [[0, 0], [1, 0], [1, 1]], "max_dwell_s": -3}]}, "positive number"),
    ({"lines": [{"name": "l", "start": [0, 0], "end": [1, 0], "max_dwell_s": 3}]}, "expected the fields end, name"),
    ({"zones": [{"name": "a", "polygon": [[0, 0], [1, 0]]}]}, r"zones\[0\].polygon: .*3 or more"),
    ({"zones": [{"name": "a", "polygon": [[0, 0], [1, 0], [1, 1]]}] * 2}, r"zones\[1\].name: 'a' is used twice"),
    ({"lines": [{"name": "l", "start": [0, 0], "end": [0, 0]}]}, "start and end are the same point"),
    ({"lines": [{"name": "l", "start": [0, 0, 0], "end": [1, 0]}]}, r"lines\[0\].start: expected \[x, y\]"),
    ({"lines": [{"name": "l", "start": ["a", 0], "end": [1, 0]}]}, "not numeric"),
    ({"zones": [], "floor_plan": {"image": "plan.png", "origin": [0, 0]}}, "floor_plan: expected the fields image"),
    ({"zones": [], "floor_plan": {"image": "plan.png", "metres_per_pixel": 0, "origin": [0, 0]}},
     "floor_plan.metres_per_pixel: expected a positive number"),
    ({"zones": [], "floor_plan": {"image": "absent.png", "metres_per_pixel": 0.1, "origin": [0, 0]}},
     "floor_plan.image: .*absent.png does not exist"),
    ({"zones": [], "floor_plan": {"image": "site.json", "metres_per_pixel": 0.1, "origin": [0, 0]}},
     "floor_plan.image: .*site.json is not a picture"),
    ({"zones": [], "floor_plan": {"image": "plan.png", "metres_per_pixel": 0.1, "origin": [0]}},
     r"floor_plan.origin: expected \[x, y\]"),
])
def test_bad_site_files_are_refused_naming_the_file_and_field(tmp_path, document, message):
    path = tmp_path / "site.json"
    path.write_text(json.dumps(document))
    _write_plan(tmp_path / "plan.png")
    if message is None:
        assert read_site(path) == Site()
        return
    with pytest.raises(InputError, match=message) as caught:
        read_site(path)
    assert str(path) in caught.value.message


def _write_plan(path, size=(40, 20)):
    """A floor picture: red in its left half, blue in its right half."""
    from PIL import Image

    pixels = np.zeros((size[1], size[0], 3), np.uint8)
    pixels[:, : size[0] // 2] = (255, 0, 0)
    pixels[:, size[0] // 2:] = (0, 0, 255)
    Image.fromarray(pixels).save(path)


def test_a_floor_plan_picture_lies_under_the_plot_where_its_origin_and_scale_put_it(tmp_path):
    from PIL import Image

    from ray3d.viz.plots import plot_floor_plan

    _write_plan(tmp_path / "plan.png")  # 40 x 20 px at 0.25 m: x in [-6, 4], y in [2, 7]
    (tmp_path / "site.json").write_text(json.dumps({
        "zones": [], "floor_plan": {"image": "plan.png", "metres_per_pixel": 0.25, "origin": [-6, 2]}}))
    site = read_site(tmp_path / "site.json")
    assert site.floor_plan.extent() == (-6.0, 4.0, 2.0, 7.0)
    assert site.floor_plan.image.shape == (20, 40, 3)
    frames, heat, corner = [], np.zeros((0, 0)), (0.0, 0.0)  # nobody: the picture alone
    plot = np.asarray(Image.open(plot_floor_plan(site, frames, heat, corner, 0.5, tmp_path / "plan-plot.png")))
    red = (plot[..., 0] > 200) & (plot[..., 1] < 60) & (plot[..., 2] < 60)
    blue = (plot[..., 2] > 200) & (plot[..., 0] < 60) & (plot[..., 1] < 60)
    assert red.sum() > 1000 and blue.sum() > 1000
    assert np.median(np.nonzero(red)[1]) < np.median(np.nonzero(blue)[1])  # the picture's left half drawn on the left


def test_the_site_schema_accepts_what_the_reader_reads_and_refuses_wrong_shapes(tmp_path):
    from importlib import resources

    import jsonschema

    schema = json.loads(resources.files("ray3d").joinpath("assets", "site.schema.json").read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    validator = jsonschema.Draft202012Validator(schema)
    _write_plan(tmp_path / "plan.png")
    document = {"zones": [{"name": "room", "polygon": ROOM.polygon.tolist(), "max_occupancy": 3, "max_dwell_s": 60}],
                "lines": [{"name": "door", "start": [0, -1], "end": [0, 1]}],
                "floor_plan": {"image": "plan.png", "metres_per_pixel": 0.05, "origin": [-1, -2]}}
    (tmp_path / "site.json").write_text(json.dumps(document))
    read_site(tmp_path / "site.json")
    validator.validate(document)
    for wrong in ({}, dict(document, doors=[]), {"zones": [{"name": "a", "polygon": [[0, 0], [1, 0]]}]},
                  {"lines": [{"name": "l", "start": [0, 0, 0], "end": [1, 0]}]},
                  {"zones": [{"name": "a", "polygon": [[0, 0], [1, 0], [1, 1]], "max_occupancy": 1.5}]},
                  dict(document, floor_plan={"image": "plan.png", "metres_per_pixel": 0, "origin": [0, 0]})):
        assert not validator.is_valid(wrong)
        (tmp_path / "wrong.json").write_text(json.dumps(wrong))
        with pytest.raises(InputError):
            read_site(tmp_path / "wrong.json")


def test_the_site_command_writes_its_tables_and_refuses_a_bad_site(tmp_path, capsys):
    import csv

    from ray3d.cli import main
    from ray3d.io.world import write_world

    times, points = _walk(np.concatenate([np.linspace(-2, 5, 71), np.linspace(5, -2, 71)[1:]]))
    joints = np.zeros((len(points), 17, 3))
    joints[:, :, :2] = points[:, None]
    result = LiftResult(joints, np.zeros((len(points), 17), bool), 10.0, np.arange(len(points)),
                        refinement={"stature_m": 1.7, "stature_interval_m": [1.6, 1.8]})
    world = write_world(tmp_path / "world.json", World({"3": result}, cameras.h36m("S9", "54138969"), "ray3d"))
    site = tmp_path / "site.json"
    site.write_text(json.dumps({"zones": [{"name": "room", "polygon": ROOM.polygon.tolist()}],
                                "lines": [{"name": "door", "start": [0, -1], "end": [0, 1]}]}))
    assert main(["site", str(world), "--site", str(site), "--out", str(tmp_path / "report")]) == 0
    out = capsys.readouterr().out
    assert "line door: 1 forward, 1 back" in out and "zone room: 2 entries, 2 exits" in out
    events = [json.loads(line) for line in (tmp_path / "report" / "events.jsonl").read_text().splitlines()]
    assert [e["event"] for e in events] == ["track started", "line crossed", "zone entered", "zone left",
                                            "zone entered", "zone left", "line crossed", "track ended"]
    with (tmp_path / "report" / "tracks.csv").open() as handle:
        (track,) = list(csv.DictReader(handle))
    assert float(track["distance_m"]) == pytest.approx(14.0) and json.loads(track["stature_interval_m"]) == [1.6, 1.8]
    assert float(track["time_in_room_s"]) == pytest.approx(2 * 3.1, abs=0.11) and track["stature_class"] == "adult"
    from PIL import Image

    with Image.open(tmp_path / "report" / "floor-plan.png") as plan:
        pixels = np.asarray(plan.convert("RGB")).astype(int)
    red = (pixels[..., 0] > 180) & (pixels[..., 1] < 80) & (pixels[..., 2] < 80)  # the line
    blue = (pixels[..., 2] > 150) & (pixels[..., 0] < 60) & (pixels[..., 1] < 140)  # the zone
    assert red.sum() > 50 and blue.sum() > 50
    with (tmp_path / "report" / "occupancy.csv").open() as handle:
        assert max(int(row["room"]) for row in csv.DictReader(handle)) == 1
    # Run again: the tables exist and are not overwritten; a bad site file is one line and exit 2.
    assert main(["site", str(world), "--site", str(site), "--out", str(tmp_path / "report")]) == 2
    assert "already exists" in capsys.readouterr().err
    site.write_text(json.dumps({"lines": [{"name": "door", "start": [0, 0], "end": [0, 0]}]}))
    assert main(["site", str(world), "--site", str(site), "--out", str(tmp_path / "other")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "same point" in err and str(site) in err


def _standing(frames: int) -> np.ndarray:
    from ray3d.demo import demo_clip

    pose = demo_clip()[0].astype(np.float64)
    pose[:, :2] -= pose[0, :2]
    pose[:, 2] -= pose[[3, 6], 2].min() - 0.07
    return np.repeat(pose[None], frames, axis=0)


def _tipped(joints: np.ndarray, angles_deg: np.ndarray, about_pelvis: bool = False) -> np.ndarray:
    """Each frame rotated about the y axis by its angle, about the feet (the whole body falls) or about the pelvis
    (the upper body bends forward; the legs stay)."""
    out = joints.copy()
    for t, angle in enumerate(np.radians(angles_deg)):
        rotation = np.array([[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]])
        pivot = joints[t, 0] if about_pelvis else np.array([joints[t, 0, 0], joints[t, 0, 1], 0.0])
        moved = slice(7, 17) if about_pelvis else slice(None)
        out[t, moved] = (joints[t, moved] - pivot) @ rotation.T + pivot
    return out


FPS = 30.0


@pytest.mark.parametrize("motion, is_fall", [
    ("fall", True), ("bend", False), ("sit", False), ("lie down slowly", False), ("fall and get up", False)])
def test_falls_are_found_and_sitting_bending_and_lying_down_are_not(motion, is_fall):
    from ray3d.site.falls import falls

    frames = int(6 * FPS)
    t = np.arange(frames) / FPS
    body = _standing(frames)
    if motion == "fall":  # over 0.6 s from 1 s, then lying still
        joints = _tipped(body, np.clip((t - 1.0) / 0.6, 0, 1) * 88)
    elif motion == "fall and get up":  # down in 0.6 s, up again after 1 s: not lying still long enough
        joints = _tipped(body, np.clip((t - 1.0) / 0.6, 0, 1) * 88 * (t < 2.6))
    elif motion == "bend":  # the upper body forward over 0.8 s, held
        joints = _tipped(body, np.clip((t - 1.0) / 0.8, 0, 1) * 90, about_pelvis=True)
    elif motion == "sit":  # 0.45 m lower over 1.5 s, upright
        joints = body - np.clip((t - 1.0) / 1.5, 0, 1)[:, None, None] * [0, 0, 0.45]
    else:  # to the floor over 4 s
        joints = _tipped(body, np.clip((t - 1.0) / 4.0, 0, 1) * 88)
    found = falls(t, joints)
    assert len(found) == int(is_fall)
    if is_fall:
        assert 1.0 <= found[0]["time_s"] <= 1.6 and found[0]["head_drop_m"] >= 1.0


def test_stature_classes_say_unsure_across_the_threshold():
    from ray3d.site.analytics import stature_class

    assert stature_class(1.72, [1.6, 1.84]) == "adult" and stature_class(1.1, [1.0, 1.2]) == "child"
    assert stature_class(1.3, [1.2, 1.4]) == "unsure" and stature_class(None, None) == "unsure"


def test_a_zones_rules_fire_when_exceeded():
    def walker(track, start_s, xs):
        times, points = _walk(xs)
        joints = np.zeros((len(points), 17, 3))
        joints[:, :, :2] = points[:, None]
        frames = np.arange(len(points)) + int(start_s * 10)
        return track, LiftResult(joints, np.zeros((len(points), 17), bool), 10.0, frames)

    # Two people in the room at once (the first stays 6 s, the second passes through).
    tracks = dict([walker("a", 0.0, np.concatenate([np.linspace(0, 2, 21), np.full(60, 2.0), np.linspace(2, 5, 31)])),
                   walker("b", 3.0, np.linspace(0, 5, 51))])
    world = World(tracks, cameras.h36m("S9", "54138969"), "ray3d")
    ruled = Zone("room", ROOM.polygon, max_occupancy=1, max_dwell_s=5.0)
    events = site_events(world, Site((ruled,), ()))
    crowded = [e for e in events if e["event"] == "occupancy above limit"]
    assert len(crowded) == 1 and crowded[0]["track"] == "b" and crowded[0]["people"] == ["a", "b"]
    long = [e for e in events if e["event"] == "dwell above limit"]
    assert len(long) == 1 and long[0]["track"] == "a" and long[0]["time_s"] == pytest.approx(1.0 + 5.0)


def test_person_frames_speed_heading_posture_zones_occupancy_and_heat():
    from ray3d.site.analytics import heat_map, person_frames
    from ray3d.site.events import replay_site

    times, points = _walk(np.linspace(0, 5, 51))  # 1 m/s along +x through the room
    joints = _standing(len(points)) + np.column_stack([points, np.zeros(len(points))])[:, None]
    result = LiftResult(joints, np.zeros((len(points), 17), bool), 10.0, np.arange(len(points)))
    world = World({"1": result, "2": dataclasses.replace(result)}, cameras.h36m("S9", "54138969"), "ray3d")
    site = Site((ROOM,), ())
    rows = person_frames(world, site)
    middle = [r for r in rows if r["track"] == "1"][25]
    assert middle["speed_m_s"] == pytest.approx(1.0, rel=0.01) and middle["heading_deg"] == pytest.approx(0.0, abs=1)
    assert middle["posture"] == "upright" and middle["zones"] == ["room"]
    replay = replay_site(world, site)
    times, counts = replay.times, replay.occupancy
    assert counts["room"].max() == 2 and counts["room"][0] == 0 and len(times) == 51
    grid, corner = heat_map(rows, 10.0, cell_m=1.0)
    assert grid.sum() == pytest.approx(2 * 51 / 10.0) and corner[0] <= 0.0


def test_frames_further_apart_than_a_fall_takes_are_no_fall_and_no_error():
    """Two frames 5 s apart (a live stream that dropped what was between) with the head 1.2 m lower in the second."""
    from ray3d.site.falls import falls

    joints = _standing(2)
    joints[1, :, 2] -= 1.2
    assert falls(np.array([0.0, 5.0]), joints) == []


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(0, 2, allow_nan=False), min_size=1, max_size=60), st.integers(1, 12))
def test_the_window_minimum_ahead_is_the_brute_force_one(values, horizon):
    from ray3d.site.falls import _window_minimum

    values = np.array(values)
    brute = [values[t + 1:t + horizon].min() if t + 1 < min(t + horizon, len(values)) else np.inf
             for t in range(len(values))]
    np.testing.assert_array_equal(_window_minimum(values, horizon), brute)


@needs_chromium
def test_the_site_report_renders_its_plan_timeline_and_events_in_headless_chromium(tmp_path, capsys):
    from ray3d.cli import main
    from ray3d.io.world import write_world

    times, points = _walk(np.concatenate([np.linspace(-2, 5, 71), np.linspace(5, -2, 71)[1:]]))
    joints = _standing(len(points)) + np.column_stack([points, np.zeros(len(points))])[:, None]
    result = LiftResult(joints, np.zeros((len(points), 17), bool), 10.0, np.arange(len(points)))
    world = write_world(tmp_path / "world.json", World({"3": result}, cameras.h36m("S9", "54138969"), "ray3d"))
    site = tmp_path / "site.json"
    site.write_text(json.dumps({"zones": [{"name": "room", "polygon": ROOM.polygon.tolist()}],
                                "lines": [{"name": "door", "start": [0, -1], "end": [0, 1]}]}))
    assert main(["site", str(world), "--site", str(site), "--out", str(tmp_path / "report")]) == 0
    capsys.readouterr()
    report = tmp_path / "report" / "report.html"
    page = report.read_text()
    assert "http://" not in page and "https://" not in page and "viewer.html#frame=" in page
    for target, fragment in ((report, ""), (tmp_path / "report" / "viewer.html", "#frame=40&follow=3")):
        assert console_errors(target, fragment) == "[]", target
    pixels = screenshot(report.as_uri(), tmp_path / "report.png", size="1300,1400")
    red = (pixels[..., 0] > 180) & (pixels[..., 1] < 80) & (pixels[..., 2] < 80)  # the line, crossings on the timeline
    blue = (pixels[..., 2] > 150) & (pixels[..., 0] < 60) & (pixels[..., 1] < 140)  # the zone, entries
    green = (pixels[..., 1] > 120) & (pixels[..., 0] < 80) & (pixels[..., 2] < 80)  # track started
    assert red.sum() > 100 and blue.sum() > 100 and green.sum() > 20


def test_a_yaml_site_file_reads_as_its_json_twin_and_broken_yaml_is_refused(tmp_path):
    path = tmp_path / "site.yaml"
    path.write_text("zones:\n  - name: room\n    polygon: [[1, -2], [4, -2], [4, 2], [1, 2]]\n    max_dwell_s: 30\n"
                    "lines:\n  - {name: door, start: [0, -1], end: [0, 1]}\n")
    site = read_site(path)
    assert site.zones[0].name == "room" and site.zones[0].max_dwell_s == 30.0 and site.lines[0].name == "door"
    path.write_text("zones: [unclosed\n")
    with pytest.raises(InputError, match="not valid YAML") as caught:
        read_site(path)
    assert str(path) in caught.value.message


def test_a_reader_that_stops_reading_is_not_an_internal_error(tmp_path, monkeypatch, capsys):
    from ray3d.cli import main, site_commands

    def closed_pipe(args):
        raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr(site_commands, "site", closed_pipe)
    assert main(["site", "w.json", "--site", "s.json", "--out", str(tmp_path)]) == 141
    assert "internal error" not in capsys.readouterr().err


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 120), st.integers(5, 80), st.floats(-2, 2), st.floats(-1.5, 1.5)),
                min_size=1, max_size=5), st.sampled_from([0.7, 1.0, 2.5, 30.0]))
def test_time_buckets_add_up_to_the_whole_runs_counts(walkers, every_s):
    from ray3d.site.analytics import by_time, zone_summaries
    from ray3d.site.events import replay_site

    tracks = {}
    for k, (start, length, x0, speed) in enumerate(walkers):
        frames = np.arange(start, start + length)
        joints = np.zeros((length, 17, 3))
        joints[:, :, 0] = (x0 + speed * (frames - start) / 10.0)[:, None] + 2.0
        joints[:, :, 1] = 0.5
        tracks[str(k)] = LiftResult(joints, np.zeros((length, 17), bool), 10.0, frames)
    world = World(tracks, cameras.h36m("S9", "54138969"), "ray3d")
    site = Site((ROOM,), (DOOR,))
    replay = replay_site(world, site)
    events, times, counts = replay.events, replay.times, replay.occupancy
    end_s = max(float(r.frames[-1]) / 10.0 for r in tracks.values())
    buckets = by_time(events, times, counts, site, every_s, end_s)
    places = {row["place"]: row for row in zone_summaries(events, site)}
    assert sum(b["room: entries"] for b in buckets) == places["room"]["entries"]
    assert sum(b["room: exits"] for b in buckets) == places["room"]["exits"]
    assert sum(b["door: forward"] for b in buckets) == places["door"]["forward"]
    assert sum(b["door: back"] for b in buckets) == places["door"]["back"]
    assert buckets[0]["start_s"] == 0 and buckets[-1]["end_s"] >= end_s
    assert max(b["room: peak occupancy"] for b in buckets) == (counts["room"].max() if len(times) else 0)


def test_the_site_command_counts_per_time_bucket_in_wall_clock_time_and_refuses_a_bad_length(tmp_path, capsys):
    import csv

    from ray3d.cli import main
    from ray3d.io.world import write_world

    times, points = _walk(np.concatenate([np.linspace(-2, 5, 71), np.linspace(5, -2, 71)[1:]]))
    joints = np.zeros((len(points), 17, 3))
    joints[:, :, :2] = points[:, None]
    result = LiftResult(joints, np.zeros((len(points), 17), bool), 10.0, np.arange(len(points)))
    world = write_world(tmp_path / "world.json", World({"3": result}, cameras.h36m("S9", "54138969"), "ray3d"))
    site = tmp_path / "site.json"
    site.write_text(json.dumps({"zones": [{"name": "room", "polygon": ROOM.polygon.tolist()}],
                                "lines": [{"name": "door", "start": [0, -1], "end": [0, 1]}]}))
    assert main(["site", str(world), "--site", str(site), "--out", str(tmp_path / "report"), "--every", "5s",
                 "--start-time", "2026-12-05T08:00:00+01:00"]) == 0
    with (tmp_path / "report" / "by-time.csv").open() as handle:
        buckets = list(csv.DictReader(handle))
    assert [b["start"] for b in buckets[:2]] == ["2026-12-05T08:00:00+01:00", "2026-12-05T08:00:05+01:00"]
    assert sum(int(b["door: forward"]) + int(b["door: back"]) for b in buckets) == 2
    assert sum(int(b["room: entries"]) for b in buckets) == 2
    assert "By time" in (tmp_path / "report" / "report.html").read_text()
    capsys.readouterr()
    for bad in (["--every", "0min"], ["--every", "soon"], ["--start-time", "2026-12-05T08:00:00"]):
        try:
            code = main(["site", str(world), "--site", str(site), "--out", str(tmp_path / "other"), *bad])
        except SystemExit as stopped:  # argparse's refusal of a value
            code = stopped.code
        assert code == 2 and len(capsys.readouterr().err.strip().splitlines()) == 1


def test_a_place_line_says_how_many_of_its_counts_people_taken_up_again_made(capsys):
    """One line per place, the same for a world's report and a store's (``ray3d site --store``, where live runs now
    re-join people too): the counts, and the share re-joined people made where there is one."""
    from ray3d.cli.printing import print_places

    print_places([{"place": "room", "kind": "zone", "entries": 3, "exits": 2, "by_rejoined_tracks": 2},
                  {"place": "door", "kind": "line", "forward": 4, "back": 1, "by_rejoined_tracks": 0}])
    assert capsys.readouterr().out.splitlines() == [
        "zone room: 3 entries, 2 exits (2 by people taken up again after a gap)", "line door: 4 forward, 1 back"]
