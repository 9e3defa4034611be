"""Sites: the site file and its refusals, line crossings with their direction and time, zone visits and their
dwell, and every event of a world's tracks in time order."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ray3d import InputError, cameras
from ray3d.io.world import LiftResult, World
from ray3d.io.site_files import read_site
from ray3d.site import CountingLine, Site, Zone, line_crossings, site_events, zone_visits

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


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.floats(1.1, 3.9), st.floats(-1.9, 1.9)), min_size=1, max_size=30))
def test_a_track_that_never_leaves_a_zone_never_leaves_it(inside):
    points = np.array(inside)
    visits = zone_visits(np.arange(len(points)) / 10.0, points, ROOM)
    assert len(visits) == 1 and visits[0]["entered_s"] is None and visits[0]["left_s"] is None


def test_a_visit_has_its_entry_exit_and_dwell():
    times, points = _walk(np.linspace(0, 5, 51))  # in the room for x in [1, 4]: from 1 s to 4 s
    (visit,) = zone_visits(times, points, ROOM)
    assert visit["entered_s"] == pytest.approx(1.0) and visit["left_s"] == pytest.approx(4.1)
    assert visit["dwell_s"] == pytest.approx(3.1)  # from the first frame inside to the first outside


def test_every_event_of_a_world_in_time_order_with_its_evidence():
    times, points = _walk(np.linspace(-2, 5, 71))
    joints = np.zeros((len(points), 17, 3))
    joints[:, :, :2] = points[:, None]
    joints[:, :, 2] = 0.9
    result = LiftResult(joints, np.zeros((len(points), 17), bool), 10.0, np.arange(100, 100 + len(points)))
    world = World({"7": result}, cameras.h36m("S9", "54138969"), "ray3d")
    events = site_events(world, Site((ROOM,), (DOOR,)))
    assert [e["event"] for e in events] == ["line crossed", "zone entered", "zone left"]
    crossed, entered, left = events
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
    ({"zones": [{"name": "a"}]}, r"zones\[0\]: expected exactly the fields name, polygon"),
    ({"zones": [{"name": "a", "polygon": [[0, 0], [1, 0]]}]}, r"zones\[0\].polygon: .*3 or more"),
    ({"zones": [{"name": "a", "polygon": [[0, 0], [1, 0], [1, 1]]}] * 2}, r"zones\[1\].name: 'a' is used twice"),
    ({"lines": [{"name": "l", "start": [0, 0], "end": [0, 0]}]}, "start and end are the same point"),
    ({"lines": [{"name": "l", "start": [0, 0, 0], "end": [1, 0]}]}, r"lines\[0\].start: expected \[x, y\]"),
    ({"lines": [{"name": "l", "start": ["a", 0], "end": [1, 0]}]}, "not numeric"),
])
def test_bad_site_files_are_refused_naming_the_file_and_field(tmp_path, document, message):
    path = tmp_path / "site.json"
    path.write_text(json.dumps(document))
    if message is None:
        assert read_site(path) == Site()
        return
    with pytest.raises(InputError, match=message) as caught:
        read_site(path)
    assert str(path) in caught.value.message


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
    assert [e["event"] for e in events] == ["line crossed", "zone entered", "zone left", "zone entered", "zone left",
                                            "line crossed"]
    with (tmp_path / "report" / "tracks.csv").open() as handle:
        (track,) = list(csv.DictReader(handle))
    assert float(track["distance_m"]) == pytest.approx(14.0) and json.loads(track["stature_interval_m"]) == [1.6, 1.8]
    assert float(track["time_in_room_s"]) == pytest.approx(2 * 3.1, abs=0.11)
    # Run again: the tables exist and are not overwritten; a bad site file is one line and exit 2.
    assert main(["site", str(world), "--site", str(site), "--out", str(tmp_path / "report")]) == 2
    assert "already exists" in capsys.readouterr().err
    site.write_text(json.dumps({"lines": [{"name": "door", "start": [0, 0], "end": [0, 0]}]}))
    assert main(["site", str(world), "--site", str(site), "--out", str(tmp_path / "other")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "same point" in err and str(site) in err
