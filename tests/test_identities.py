"""Who is who over short gaps (``ray3d.video.identities``): a track taken up again where its walk led, in the same
clothes, is one identity; never two people at once, never across an impossible walk, never a crossing pair with
their clothes swapped; the world file keeps the re-joins, and a line is counted once for a person re-joined."""

from __future__ import annotations

import json
from importlib import resources

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ray3d import cameras
from ray3d.io.world import LiftResult, World, read_world, write_world
from ray3d.lifting.options import VideoOptions
from ray3d.site import CountingLine, Site, site_events
from ray3d.site.analytics import zone_summaries
from ray3d.video.identities import REJOIN_WITHIN_S, rejoin_tracks
from ray3d.video.pipeline import follow_people
from ray3d.video.track import Track

FPS = 10.0
RED, BLUE = np.eye(32)[0], np.eye(32)[9]  # two clothes colours with nothing in common


def _track(name: str, frames, start_xy, velocity_xy, colour=RED, floor_sd_m=0.0) -> Track:
    frames = list(frames)
    times = (np.array(frames) - frames[0]) / FPS
    floor = [np.asarray(start_xy, float) + np.asarray(velocity_xy, float) * t for t in times]
    return Track(name, frames, [None] * len(frames), floor, colour, [np.eye(2) * floor_sd_m ** 2] * len(frames))


def _walker(name: str, frames, velocity=(1.2, 0.0), colour=RED, origin=(0.0, 0.0), floor_sd_m=0.0) -> Track:
    """A person walking from ``origin`` at frame 0 at ``velocity``, seen in ``frames`` (each floor point with
    that standard deviation)."""
    frames = list(frames)
    return _track(name, frames, np.asarray(origin) + np.asarray(velocity) * frames[0] / FPS, velocity, colour,
                  floor_sd_m)


def test_a_person_lost_for_a_second_and_a_half_is_one_identity_with_the_gap_unseen():
    first, second = _walker("0", range(0, 30)), _walker("1", range(45, 80))
    identities, rejoins = rejoin_tracks([second, first], FPS)
    assert len(identities) == 1 and identities[0].id == "0"
    assert identities[0].frames == list(range(0, 30)) + list(range(45, 80))
    (rejoin,) = rejoins
    assert rejoin.joined == "1" and rejoin.after_frame == 29 and rejoin.gap_s == pytest.approx(1.6)
    assert rejoin.miss_m < 0.01 and rejoin.unlike == pytest.approx(0.0)


def test_two_tracks_at_once_an_impossible_walk_and_a_long_gap_stay_apart():
    first = _walker("0", range(0, 30))
    overlapping = _walker("1", range(25, 60))
    assert len(rejoin_tracks([first, overlapping], FPS)[0]) == 2
    far = _walker("2", range(40, 70), origin=(0.0, 6.0))  # 1 s later, 6 m off the walk
    assert len(rejoin_tracks([first, far], FPS)[0]) == 2
    late = _walker("3", range(30 + int(FPS * (REJOIN_WITHIN_S + 1)), 120))
    assert len(rejoin_tracks([first, late], FPS)[0]) == 2
    turned = _track("4", range(40, 70), first.floor[-1] + [1.2 * 1.0, 0.0], (-1.4, 0.0))  # back the other way
    assert len(rejoin_tracks([first, turned], FPS)[0]) == 2


def test_the_walk_reaches_as_far_as_the_floor_points_are_uncertain():
    """The same start, 1.6 m off where the walk led after 1 s: a far person, whose every floor point is uncertain
    by half a metre (their walk read from them too), is re-joined; a near person, placed to a few centimetres, is
    not (a stride's allowance would not take them there). The reach the re-join states is the gate's that way."""
    for floor_sd_m, joined in ((0.5, True), (0.03, False)):
        first = _walker("0", range(0, 30), floor_sd_m=floor_sd_m)
        off = _walker("1", range(40, 70), origin=(0.0, 1.6), floor_sd_m=floor_sd_m)
        identities, rejoins = rejoin_tracks([first, off], FPS)
        assert (len(identities) == 1) is joined
        if joined:
            (rejoin,) = rejoins
            assert rejoin.miss_m == pytest.approx(1.6) and rejoin.miss_m <= rejoin.reach_m < 4.0
    # However uncertain the places, a walk the other way at walking pace is another person.
    first = _walker("0", range(0, 30), floor_sd_m=0.05)
    back = _track("2", range(40, 70), first.floor[-1] + [1.2, 0.0], (-1.4, 0.0), floor_sd_m=0.05)
    assert len(rejoin_tracks([first, back], FPS)[0]) == 2


def test_a_person_who_turns_back_while_hidden_is_one_identity_but_not_a_second_later():
    """A walker at 1.2 m/s is hidden, turns round at a steady 1 m/s2 and comes out where they went in, walking back
    (the mean of the two walks is standing still): after 2.4 s that is them; the same turn made in 0.5 s is not a
    walk (2.4 m/s of velocity changed), whoever it is. One who slowed to a stop is found where they stopped."""
    first = _walker("0", range(0, 30))
    for gap_frames, joined in ((24, True), (5, False)):
        back = _track("1", range(29 + gap_frames, 29 + gap_frames + 30), first.floor[-1], (-1.2, 0.0))
        assert (len(rejoin_tracks([first, back], FPS)[0]) == 1) is joined
    # Slowed from 1.2 m/s to a stop over the 2.4 s: 1.44 m on, where the walk alone would have led 2.9 m on.
    stopped = _track("2", range(53, 83), first.floor[-1] + [1.44, 0.0], (0.0, 0.0))
    (rejoin,) = rejoin_tracks([first, stopped], FPS)[1]
    assert rejoin.miss_m == pytest.approx(0.0, abs=0.02)


def test_a_short_track_in_the_gap_does_not_lend_the_person_its_colours():
    """A walker seen for 3 s, then 0.3 s on a box whose colours are read half off somebody beside them, then again:
    the short track is them (near enough in colour, on their walk), and the walker's colours stay what 3 s of
    them showed, so the walker seen again is them, though unlike the short track's colours."""
    walker_colour, later_colour = np.eye(32)[0] * 0.6 + np.eye(32)[1] * 0.4, np.eye(32)[0] * 0.4 + np.eye(32)[1] * 0.6
    mixed = np.eye(32)[0] * 0.8 + np.eye(32)[2] * 0.2
    first = _walker("0", range(0, 30), colour=walker_colour)
    short = _walker("1", range(38, 41), colour=mixed)
    again = _walker("2", range(48, 80), colour=later_colour)
    identities, rejoins = rejoin_tracks([first, short, again], FPS)
    assert [(r.identity, r.joined) for r in rejoins] == [("0", "1"), ("0", "2")] and len(identities) == 1
    assert rejoins[1].unlike < 0.3  # against 3.3 s of the walker's colours, not 0.66 against the short track's


def test_the_people_reported_are_the_identities_followed_long_enough_a_fragment_in_a_gap_left_out():
    # A walker lost twice, with a 0.7 s fragment on a box read wrongly (2 m off their walk) in the first gap.
    walker = [_walker("0", range(0, 30)), _walker("2", range(45, 80)), _walker("3", range(95, 140))]
    fragment = _walker("1", range(33, 40), origin=(0.0, 2.0), colour=BLUE)
    people = follow_people(walker + [fragment], FPS, 140, VideoOptions())
    assert [t.id for t in people.kept] == ["0"] and [t.id for t in people.dropped] == ["1"]
    assert people.kept[0].frames == list(range(0, 30)) + list(range(45, 80)) + list(range(95, 140))
    assert [r.joined for r in people.rejoins] == ["2", "3"] and people.shortest_s == 1.0
    # Without the re-join each piece is a person; with no minimum the fragment is one too.
    alone = follow_people(walker + [fragment], FPS, 140, VideoOptions(rejoin_s=0.0, min_track_s=0.0))
    assert sorted(t.id for t in alone.kept) == ["0", "1", "2", "3"] and not alone.rejoins
    # A clip of 1.2 s keeps whoever was followed for half of it (0.6 s), not the 1 s asked.
    short_clip = follow_people([fragment], FPS, 12, VideoOptions())
    assert [t.id for t in short_clip.kept] == ["1"] and short_clip.shortest_s == pytest.approx(0.6)


def test_a_crossing_pair_is_told_apart_by_their_clothes_not_by_where_they_are():
    """Two people walking side by side, 0.4 m apart, are lost together (one behind the other); after the gap each
    starts within walking reach of both. The track where the red walker's walk leads wears blue: it continues the
    blue walker, never the red one (a swap refused), and the other way round."""
    red = _walker("0", range(0, 30), (1.2, 0.0), RED, origin=(0.0, 0.0))
    blue = _walker("1", range(0, 30), (1.2, 0.0), BLUE, origin=(0.0, 0.4))
    blue_where_red_went = _walker("2", range(40, 70), (1.2, 0.0), BLUE, origin=(0.0, 0.0))
    red_where_blue_went = _walker("3", range(40, 70), (1.2, 0.0), RED, origin=(0.0, 0.4))
    identities, rejoins = rejoin_tracks([red, blue, blue_where_red_went, red_where_blue_went], FPS)
    assert sorted((r.identity, r.joined) for r in rejoins) == [("0", "3"), ("1", "2")] and len(identities) == 2
    stranger = _walker("4", range(40, 70), (1.2, 0.0), np.eye(32)[20], origin=(0.0, 0.0))  # nobody's clothes
    assert not rejoin_tracks([red, stranger], FPS)[1]


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 200), st.integers(3, 40), st.floats(-1.5, 1.5), st.floats(-1.5, 1.5),
                          st.floats(-5, 5), st.sampled_from([0, 9])), min_size=1, max_size=8))
def test_identities_never_overlap_keep_every_frame_once_and_join_only_within_reach(specs):
    tracks = [_track(str(k), range(start, start + length), (x0, 0.0), (vx, vy), np.eye(32)[colour])
              for k, (start, length, vx, vy, x0, colour) in enumerate(specs)]
    identities, rejoins = rejoin_tracks(tracks, FPS)
    for identity in identities:
        assert np.all(np.diff(identity.frames) > 0)  # one person is never two at once
    given_frames = sorted((t.id, f) for t in tracks for f in t.frames)
    owner = {r.joined: r.identity for r in rejoins}

    def root(name: str) -> str:
        while name in owner:
            name = owner[name]
        return name

    assert sorted((root(t.id), f) for t in tracks for f in t.frames) == \
        sorted((i.id, f) for i in identities for f in i.frames)
    assert len(given_frames) == sum(len(i.frames) for i in identities)
    for rejoin in rejoins:
        assert 0 < rejoin.gap_s <= REJOIN_WITHIN_S and rejoin.miss_m <= rejoin.reach_m and rejoin.unlike < 0.6


def test_a_line_counts_a_rejoined_person_once_and_the_world_file_keeps_the_rejoin(tmp_path):
    """A person lost while crossing a line: as two tracks the line is crossed by neither (one ends before it, the
    other starts after it); as one identity, the frames between filled in, it is crossed once, by a re-joined
    track, which the place's row says."""
    camera = cameras.h36m("S9", "54138969")
    frames = np.arange(0, 60)
    joints = np.zeros((60, 17, 3))
    joints[:, :, 0] = (1.2 * frames / FPS)[:, None]
    joints[:, :, 2] = 0.9
    seen = np.ones((60, 17), bool)
    seen[25:40] = False  # unseen while crossing x = 3.6 m
    line = CountingLine("door", np.array([3.6, -5.0]), np.array([3.6, 5.0]))
    apart = World({"0": LiftResult(joints[:25], np.zeros((25, 17), bool), FPS, frames[:25]),
                   "1": LiftResult(joints[40:], np.zeros((20, 17), bool), FPS, frames[40:])}, camera, "test")
    assert not [e for e in site_events(apart, Site((), (line,))) if e["event"] == "line crossed"]
    rejoined = {"0": [{"identity": "0", "joined": "1", "after_frame": 24, "gap_s": 1.6, "miss_m": 0.0,
                       "reach_m": 1.35, "unlike": 0.0}]}
    one = World({"0": LiftResult(joints, ~seen, FPS, frames)}, camera, "test", rejoined=rejoined)
    events = site_events(one, Site((), (line,)))
    assert [e["direction"] for e in events if e["event"] == "line crossed"] == ["forward"]
    (row,) = zone_summaries(events, Site((), (line,)), one.rejoined)
    assert row["forward"] + row["back"] == 1 and row["by_rejoined_tracks"] == 1
    write_world(tmp_path / "w.json", one)
    assert read_world(tmp_path / "w.json").rejoined == rejoined
    jsonschema = pytest.importorskip("jsonschema")
    schema = json.loads(resources.files("ray3d").joinpath("assets", "world.schema.json").read_text())
    jsonschema.validate(json.loads((tmp_path / "w.json").read_text()), schema)


def test_one_rule_says_a_track_is_too_short_offline_and_live():
    """``Track.too_short``: kept from exactly ``shortest_s`` on, otherwise the reason both ``ray3d video`` and
    ``ray3d live`` give."""
    from ray3d.video.track import Track

    second = Track("7", list(range(10)))  # 10 frames at 10 frames/s: 1.0 s
    assert second.too_short(10.0, 1.0) is None
    assert second.too_short(10.0, 1.5) == "seen for 1.00 s (under 1.50 s)"
    assert Track("8", [4]).too_short(25.0, 0.04) is None  # one frame is one frame period
    # A person taken up from a run cut off was followed before the cut: their part here is kept however short.
    assert Track("9", [0, 1], carried=True).too_short(10.0, 1.0) is None
