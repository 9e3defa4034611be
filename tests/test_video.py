"""The video pipeline on generated videos of several stick figures walking: a stub detector (which checks each
figure is drawn where it says) exercises reading, tracking, lifting every track, the world file, the
detections, the viewer and the overlay; the tracker and the proposals are tested on their own; the real
landmark network runs when the video extra is installed."""

from __future__ import annotations

import dataclasses
import json
from importlib import resources
from pathlib import Path
from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from ray3d import Camera, InputError, Lifter
from ray3d.cli import main
from ray3d.demo import demo_clip
from ray3d.io.keypoints import read_keypoints
from ray3d.io.world import read_world
from ray3d.lifting.options import VideoOptions
from ray3d.skeleton import H36M17
from ray3d.video import DETECTORS, Detection, FloorTracker, lift_video, read_video_info
from ray3d.video.boxes import box_inside, box_overlap
from ray3d.video.clothes import clothes_boxes, clothes_colour, colour_distance
from ray3d.video.proposals import ForegroundProposals, median_background, person_height_px

SIZE, FPS, FRAMES = (640, 480), 20.0, 40
CAMERA = Camera.from_height_pitch(3.0, 15.0, SIZE, hfov_deg=70.0)


def _walker(start_xy, velocity_xy, frames=FRAMES, fps=FPS):
    """(T, 17, 3) world joints: the bundled clip's pose relative to its pelvis, carried along a straight line."""
    clip = demo_clip()[:frames]
    relative = clip - np.concatenate([clip[:, :1, :2], np.zeros((frames, 1, 1))], axis=-1)
    path = np.asarray(start_xy) + np.outer(np.arange(frames) / fps, velocity_xy)
    return relative + np.concatenate([path, np.zeros((frames, 1))], axis=-1)[:, None]


def _crossing_people():
    """Three people: two crossing in the image at different depths, one apart."""
    return [_walker((6.0, -2.0), (0.0, 1.4)), _walker((9.0, 2.5), (0.0, -1.5)), _walker((5.0, 3.0), (0.8, 0.0))]


def _render(path, people_pixels, hidden=()):
    """A video of stick figures (white bones on grey, the pelvis a filled disc); ``hidden`` = (person, frame)
    pairs not drawn."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), FPS, SIZE)
    for t in range(FRAMES):
        frame = np.full((SIZE[1], SIZE[0], 3), 60, np.uint8)
        for person, pixels in enumerate(people_pixels):
            if (person, t) in hidden:
                continue
            for child, parent in enumerate(H36M17.parents):
                if parent >= 0:
                    a, b = (tuple(int(v) for v in pixels[t, i]) for i in (child, parent))
                    cv2.line(frame, a, b, (255, 255, 255), 3)
            cv2.circle(frame, tuple(int(v) for v in pixels[t, 0]), 5, (255, 255, 255), -1)
        writer.write(frame)
    writer.release()
    return path


class StubDetector:
    """The known pixels of every person drawn in a frame, after checking each is drawn there."""

    layout = "h36m17"

    def __init__(self, people_pixels, hidden=(), start=0):
        self.people, self.hidden, self.calls, self.prepared = people_pixels, set(hidden), start, 0

    def prepare(self, frames):
        self.prepared = len(frames)

    def __call__(self, frame):
        assert frame.shape == (SIZE[1], SIZE[0], 3) and frame.dtype == np.uint8
        t = self.calls
        self.calls += 1
        found = []
        for person, pixels in enumerate(self.people):
            if (person, t) in self.hidden:
                continue
            u, v = (int(round(x)) for x in pixels[t, 0])
            assert frame[v, u].mean() > 200, "the pelvis disc is not where the stub expects it"
            found.append(Detection(pixels[t].copy(), np.ones(17), 0.9))
        return found


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    people = _crossing_people()
    pixels = [CAMERA.project(p) for p in people]
    hidden = {(0, t) for t in range(18, 21)}  # a short occlusion while crossing: filled in, not split
    path = _render(tmp_path_factory.mktemp("video") / "walk.mp4", pixels, hidden)
    return path, people, pixels, hidden


def _owner(track, people):
    """Which person a lifted track follows in every frame (their nearest pelvis on the floor)."""
    distances = np.stack([np.linalg.norm(track.root[:, :2] - p[track.frames, 0, :2], axis=-1) for p in people])
    return distances.argmin(axis=0), distances.min(axis=0)


def test_every_person_is_tracked_and_lifted_into_one_world_frame(scene, tmp_path):
    path, people, pixels, hidden = scene
    info = read_video_info(path)
    assert info.image_size == SIZE and info.frames == FRAMES and info.fps == pytest.approx(FPS)
    detector = StubDetector(pixels, hidden)
    result = lift_video(path, CAMERA, tmp_path / "out", detector, Lifter.load(), progress=False)
    assert detector.prepared > 0 and result.frames == FRAMES and not result.dropped
    assert set(result.files) == {"world", "keypoints", "viewer", "overlay"}
    world = read_world(result.files["world"])
    assert len(world.tracks) == 3
    owners = set()
    for name, track in world.tracks.items():
        owner, distance = _owner(track, people)
        assert len(set(owner)) == 1, f"track {name} switches between people"  # the crossing keeps who is who
        assert np.median(distance) < 1.0  # metres: a sanity bound, not an accuracy claim
        owners.add(int(owner[0]))
        if owner[0] == 0:  # the occluded frames are filled in, marked, and the track is not split
            assert track.interpolated[18:21].all() and not track.interpolated[:18].any()
    assert owners == {0, 1, 2}
    # The detections read back with their tracks, and lifting them again gives the same world.
    keypoints = read_keypoints(result.files["keypoints"])
    assert sorted(set(keypoints.tracks.tolist())) == sorted(world.tracks)  # one type of id, a string
    assert len(keypoints.frames) == 3 * FRAMES - len(hidden)
    assert main(["lift", "--keypoints", str(result.files["keypoints"]), "--camera-height", "3", "--pitch", "15",
                 "--hfov", "70", "--image-size", "640x480", "--smooth-3d", "savgol",  # as ray3d video does
                 "--out", str(tmp_path / "again.json")]) == 0
    again = read_world(tmp_path / "again.json")
    for name in world.tracks:
        np.testing.assert_allclose(again.track(name).joints, world.track(name).joints, atol=1e-4)
    viewer = json.loads(result.files["viewer"].read_text().split("const DATA = ", 1)[1].split(";\n", 1)[0])
    assert set(viewer["sequences"]) == set(world.tracks) and viewer["first"] == 0 and viewer["last"] == FRAMES - 1
    overlay = read_video_info(result.files["overlay"])
    assert overlay.frames == FRAMES and overlay.image_size == SIZE


def track_name(world) -> str:
    return next(iter(world.tracks))


def test_a_gap_longer_than_max_gap_splits_the_track_and_nothing_is_drawn_where_nobody_was(tmp_path):
    person = _walker((6.0, -1.5), (0.0, 1.0))
    pixels = [CAMERA.project(person)]
    hidden = {(0, t) for t in list(range(0, 5)) + list(range(16, 30))}  # 0.7 s unseen in the middle
    path = _render(tmp_path / "gap.mp4", pixels, hidden)
    # Taken up again after the gap (the default: where the walk led, within 3 s): one person, the gap unseen.
    joined = lift_video(path, CAMERA, tmp_path / "joined", StubDetector(pixels, hidden), Lifter.load(),
                        video_options=VideoOptions(min_track_s=0.2), overlay=False, progress=False)
    (track,) = joined.world.tracks.values()
    assert (int(track.frames[0]), int(track.frames[-1])) == (5, FRAMES - 1)
    unseen = track.interpolated.all(axis=1)
    assert np.array_equal(np.flatnonzero(unseen), np.arange(16, 30) - 5)
    assert [r["gap_s"] for r in joined.world.rejoined[track_name(joined.world)]] == [pytest.approx(15 / FPS)]
    result = lift_video(path, CAMERA, tmp_path / "out", StubDetector(pixels, hidden), Lifter.load(),
                        video_options=VideoOptions(min_track_s=0.2, rejoin_s=0), progress=False)
    spans = sorted((int(t.frames[0]), int(t.frames[-1])) for t in result.world.tracks.values())
    assert spans == [(5, 15), (30, FRAMES - 1)]
    assert not any(t.interpolated.any() for t in result.world.tracks.values())
    # Frames before the first detection and inside the gap hold no skeleton: the overlay equals the input there.
    source = cv2.VideoCapture(str(path))
    drawn = cv2.VideoCapture(str(result.files["overlay"]))
    difference = []
    for _ in range(FRAMES):
        changed = np.abs(source.read()[1].astype(int) - drawn.read()[1].astype(int)).max(axis=-1) > 60
        difference.append(int(changed.sum()))  # pixels the overlay painted (video coding changes a few levels)
    difference = np.array(difference)
    empty = np.array([t < 5 or 16 <= t < 30 for t in range(FRAMES)])
    assert difference[empty].max() < 20 < 200 < difference[~empty].min()


def test_tracker_keeps_ids_through_an_occluded_crossing_and_ends_tracks_after_the_gap():
    people = [_walker((7.0, -2.0), (0.0, 1.5), 60), _walker((10.0, 2.0), (0.0, -1.5), 60)]
    pixels = [CAMERA.project(p) for p in people]
    tracker = FloorTracker(CAMERA, FPS, "h36m17", max_gap_s=0.5)
    frame = np.full((SIZE[1], SIZE[0], 3), 60, np.uint8)
    for t in range(60):
        # The nearer person hides the farther one for 4 frames while they cross; person 1 leaves at frame 45.
        seen = [p for p in (0, 1) if not (p == 1 and (24 <= t < 28 or t >= 45))]
        tracker.update(t, [Detection(pixels[p][t], np.ones(17), 0.9) for p in seen], frame)
    tracks = tracker.tracks()
    assert len(tracks) == 2
    for track in tracks:
        first = track.detections[0].pixels[0]
        person = int(np.argmin([np.linalg.norm(p[track.frames[0], 0] - first) for p in pixels]))
        for f, d in zip(track.frames, track.detections):
            np.testing.assert_allclose(d.pixels, pixels[person][f])  # never the other person's detection
    assert sorted(len(t.frames) for t in tracks) == [41, 60]


@pytest.mark.parametrize("second_xy, squeezed", [((7.0, -2.5), 0.0), ((9.0, -2.0), 0.0), ((7.0, -2.5), 0.55)],
                         ids=["side by side", "2 m behind, crossing", "side by side, a box short of one"])
def test_one_box_for_two_people_is_given_to_neither(second_xy, squeezed):
    """Two people walking side by side, 0.5 m apart, or one 2 m behind the other and to the side, that the detector
    sees as one box for 6 frames: neither track takes it (whichever did would carry on as the other when they
    part); both skip those frames and keep their own person before and after. Also where the box is a compromise
    that leaves more than half of one of them outside (``squeezed``: its edge on that side moved in by that share
    of the gap between their edges). One of them alone, the other missed, is still followed."""
    people = [_walker((7.0, -3.0), (0.0, 1.2), 50), _walker(second_xy, (0.0, 1.2), 50)]
    pixels = [CAMERA.project(p) for p in people]
    tracker = FloorTracker(CAMERA, FPS, "h36m17", max_gap_s=0.5)
    frame = np.full((SIZE[1], SIZE[0], 3), 60, np.uint8)
    near_edge = pixels[1][..., 0].min(axis=-1) - pixels[0][..., 0].min(axis=-1)  # (T,) how far left of the first
    squeezed_second = pixels[1] - np.stack([squeezed * near_edge[:, None], np.zeros_like(near_edge)[:, None]], -1)
    both = np.concatenate([pixels[0][:, :9], squeezed_second[:, 9:]], axis=1)  # a box around the two of them
    if squeezed:
        last = [Detection(p[19], np.ones(17), 0.9).box for p in pixels]
        assert 0.4 <= box_inside(last[1], Detection(both[20], np.ones(17), 0.9).box) < 0.5  # less than half inside
    for t in range(50):
        found = [pixels[0][t]] if 34 <= t < 37 else [both[t]] if 20 <= t < 26 else [pixels[0][t], pixels[1][t]]
        tracker.update(t, [Detection(p, np.ones(17), 0.9) for p in found], frame)
    tracks = tracker.tracks()
    assert len(tracks) == 2
    for track in tracks:
        person = int(np.argmin([np.linalg.norm(p[track.frames[0], 0] - track.detections[0].pixels[0]) for p in pixels]))
        for f, d in zip(track.frames, track.detections):
            np.testing.assert_allclose(d.pixels, pixels[person][f])  # never the box of both, never the other
        assert not set(range(20, 26)) & set(track.frames)
        assert set(range(34, 37)) <= set(track.frames) if person == 0 else not set(range(34, 37)) & set(track.frames)


def test_clothes_colours_tell_jeans_from_black_trousers_under_the_same_jacket():
    """Two people in one black jacket, one in blue jeans and one in black trousers: their clothes' colours are
    far apart (the legs are read as well as the torso), while each is close to themself seen again."""
    pose = CAMERA.project(_walker((6.0, 0.0), (0.0, 0.0), 1))[0]
    seen = np.ones(17, bool)
    detection = Detection(pose, np.ones(17), 0.9)
    torso, legs = clothes_boxes(detection, pose, seen)
    assert torso[3] <= legs[3] and legs[1] < torso[3]  # the legs' box below the torso's, from the hips

    def dressed(trousers_rgb, seed):  # the camera's noise differs from frame to frame
        frame = np.full((SIZE[1], SIZE[0], 3), 128.0)
        frame[int(torso[1]):int(torso[3]) + 1, int(torso[0]):int(torso[2]) + 1] = (30, 30, 35)
        frame[int(torso[3]) + 1:int(legs[3]) + 1, int(legs[0]):int(legs[2]) + 1] = trousers_rgb
        noisy = frame + np.random.default_rng(seed).normal(0.0, 3.0, frame.shape)
        return clothes_colour(np.clip(noisy, 0, 255).astype(np.uint8), torso, legs)

    jeans, black = dressed((60, 90, 150), 0), dressed((35, 35, 40), 1)
    # The torsos tell them apart not at all; half the histogram unlike is half the way to nothing in common.
    assert colour_distance(jeans, black) > 0.5 > 0.2 > max(colour_distance(black, dressed((35, 35, 40), 2)),
                                                           colour_distance(jeans, dressed((60, 90, 150), 3)))


def test_a_person_keeps_their_colours_while_somebody_may_be_hidden_behind_them():
    """A man in red stands in front of a man the detector then loses behind him; for 7 frames the red man's box
    shows some blue (the hidden man's clothes beside his legs). His track does not learn blue from it while the
    hidden man's last box lies under his: when the blue is gone, his colours are red as before."""
    people = [_walker((6.0, 0.0), (0.0, 0.0), 17), _walker((8.0, 0.0), (0.0, 0.0), 17)]
    pixels = [CAMERA.project(p) for p in people]
    boxes = [Detection(p[0], np.ones(17), 0.9).box for p in pixels]
    assert box_overlap(boxes[0][None], boxes[1][None])[0, 0] > 0.05  # the far man's box lies under the near one's

    def dressed(t: int, blue_legs: bool) -> np.ndarray:  # his clothes where his joints are in frame t
        torso, legs = clothes_boxes(Detection(pixels[0][t], np.ones(17), 0.9), pixels[0][t], np.ones(17, bool))
        frame = np.full((SIZE[1], SIZE[0], 3), 128, np.uint8)
        for box in (torso, legs):
            frame[int(box[1]):int(box[3]) + 1, int(box[0]):int(box[2]) + 1] = (200, 30, 40)
        if blue_legs:
            frame[int(legs[1]):int((legs[1] + legs[3]) / 2), int(legs[0]):int(legs[2]) + 1] = (30, 40, 200)
        return frame

    tracker = FloorTracker(CAMERA, FPS, "h36m17", max_gap_s=0.5)
    for t in range(17):
        seen = [0, 1] if t < 10 else [0]
        tracker.update(t, [Detection(pixels[p][t], np.ones(17), 0.9) for p in seen], dressed(t, 10 <= t < 17))
    (red,) = [t for t in tracker.tracks() if len(t.frames) == 17]
    torso, legs = clothes_boxes(Detection(pixels[0][16], np.ones(17), 0.9), pixels[0][16], np.ones(17, bool))
    assert colour_distance(red.colour, clothes_colour(dressed(16, False), torso, legs)) < 0.1


def test_given_every_eighth_frame_a_person_missed_twice_in_a_row_keeps_their_track():
    """A live camera under load takes every k-th frame: at every 8th, two misses in a row span 16 frames (0.8 s at
    20 frames/s, over ``max_gap_s``'s 10), yet the person is kept as at the full rate once the tracker is told
    ``frames_apart``; a third miss in a row ends them, as a long gap in time does at the full rate."""
    person = _walker((7.0, -2.0), (0.0, 1.2), 80)
    pixels = CAMERA.project(person)
    frame = np.full((SIZE[1], SIZE[0], 3), 60, np.uint8)

    def tracks_of(frames_apart: int, missed: set[int], told: bool = True) -> set:
        tracker = FloorTracker(CAMERA, FPS, "h36m17", max_gap_s=0.5)
        tracker.frames_apart = frames_apart if told else 1
        for t in range(0, 80, frames_apart):
            tracker.update(t, [] if t in missed else [Detection(pixels[t], np.ones(17), 0.9)], frame)
        return {t.id for t in tracker.tracks()}

    assert len(tracks_of(8, {32, 40})) == 1
    assert len(tracks_of(8, {32, 40}, told=False)) == 2
    assert len(tracks_of(8, {32, 40, 48})) == 2
    assert len(tracks_of(1, set(range(24, 36)))) == 2  # at the full rate 0.6 s unseen is over max_gap_s


def test_tracker_needs_several_hits_before_a_track_exists():
    tracker = FloorTracker(CAMERA, FPS, "h36m17", confirm_hits=3)
    frame = np.full((SIZE[1], SIZE[0], 3), 60, np.uint8)
    pose = CAMERA.project(_walker((6.0, 0.0), (0.0, 0.0), 1))[0]
    tracker.update(0, [Detection(pose, np.ones(17), 0.9)], frame)
    tracker.update(1, [], frame)  # a one-off detection: never a track
    for t in range(2, 5):
        tracker.update(t, [Detection(pose, np.ones(17), 0.9)], frame)
    assert [t.frames for t in tracker.tracks()] == [[2, 3, 4]]


def _restarted(carried, people_by_frame, frame=None) -> list:
    """The tracks of a run's tracker that takes ``carried`` people up (its own ids "2-..."), given each frame's
    people ((17, 2) pixels each) from frame 0 on, in a grey frame unless ``frame`` is given."""
    frame = np.full((SIZE[1], SIZE[0], 3), 60, np.uint8) if frame is None else frame
    tracker = FloorTracker(CAMERA, FPS, "h36m17", confirm_hits=3, id_prefix="2-", carried=carried)
    for t, people in enumerate(people_by_frame):
        tracker.update(t, [Detection(p, np.ones(17), 0.9) for p in people], frame)
    return tracker.tracks()


def test_tracker_gives_a_person_where_a_cut_off_run_left_somebody_their_id_in_its_first_seconds_only():
    """Issue 67, item 3: of the people a run cut off left in view, one found again where they could have walked to
    takes up their id; a stranger elsewhere gets a new one, and so does somebody found where a carried person
    was once ``CLAIM_S`` has passed."""
    from ray3d.site.events import CarriedPerson
    from ray3d.video.tracking import CLAIM_S

    frame = np.full((SIZE[1], SIZE[0], 3), 60, np.uint8)
    back = CAMERA.project(_walker((6.0, 0.0), (0.0, 0.0), 1))[0]     # 0.3 m from where 1-4 was left
    stranger = CAMERA.project(_walker((9.0, 2.5), (0.0, 0.0), 1))[0]  # 3.5 m from 1-4, 3.7 m from 1-7
    late = CAMERA.project(_walker((8.0, -2.0), (0.0, 0.0), 1))[0]     # where 1-7 was left, too late
    carried = [CarriedPerson("1-4", (6.3, 0.0), 0.0, 0.0), CarriedPerson("1-7", (8.0, -2.0), 0.0, 0.0)]
    tracker = FloorTracker(CAMERA, FPS, "h36m17", confirm_hits=3, id_prefix="2-", carried=carried)
    late_from = int(CLAIM_S * FPS) + 2
    for t in range(late_from + 4):
        people = [back, stranger] + ([late] if t >= late_from else [])
        tracker.update(t, [Detection(p, np.ones(17), 0.9) for p in people], frame)
    assert sorted(t.id for t in tracker.tracks()) == ["1-4", "2-0", "2-1"]


def test_tracker_takes_a_carried_person_up_where_their_tracker_put_them_before_their_lifted_place():
    """A carried person's lifted pelvis may lie a metre off where the tracker measured them (a far person): the
    claim goes by the tracker's own place (``CarriedPerson.tracked``) where the store kept one, so the person
    found there takes up the id, not the one found near the lifted place."""
    from ray3d.site.events import CarriedPerson

    here = CAMERA.project(_walker((6.0, 0.0), (0.0, 0.0), 1))[0]
    tracked = [CarriedPerson("1-4", (7.5, 0.0), 0.0, 0.0, tracked=(6.1, 0.0, 0.0))]
    assert [t.id for t in _restarted(tracked, [[here]] * 4)] == ["1-4"]
    lifted_only = [CarriedPerson("1-4", (7.5, 0.0), 0.0, 0.0)]
    assert [t.id for t in _restarted(lifted_only, [[here]] * 4)] == ["2-0"]  # 1.5 m from it at 0.3 s: out of reach


def test_of_two_carried_people_the_one_whose_walk_led_there_is_taken_up_and_their_walk_goes_on():
    """Two people in view at a cut: one standing 0.8 m from where somebody is found, the other last placed 1.3 m
    away 0.8 s before, walking towards there at 1.5 m/s. The walker is taken up (their walk led within 0.15 m), and
    the track goes on with the walk read before the cut, not only what its first three frames say."""
    from ray3d.site.events import CarriedPerson

    frame = np.full((SIZE[1], SIZE[0], 3), 60, np.uint8)
    walker = CAMERA.project(_walker((6.0, -0.2), (0.0, 1.5), 4))
    standing = CarriedPerson("1-4", (6.0, 0.6), -0.8, 0.0, tracked=(6.0, 0.6, -0.8), walk=(0.0, 0.0))
    walking = CarriedPerson("1-7", (6.0, -1.5), -0.8, 0.0, tracked=(6.0, -1.5, -0.8), walk=(0.0, 1.5))

    def taken_up(*carried: CarriedPerson):
        tracker = FloorTracker(CAMERA, FPS, "h36m17", confirm_hits=3, id_prefix="2-", carried=carried)
        for t in range(3):
            tracker.update(t, [Detection(walker[t], np.ones(17), 0.9)], frame)
        return tracker.tracks()[0]

    track = taken_up(standing, walking)
    assert track.id == "1-7"
    placed_only = [dataclasses.replace(person, walk=None) for person in (standing, walking)]
    assert taken_up(*placed_only).id == "1-4"  # by place alone, the nearer
    assert abs(track.walk[1] - 1.5) < 0.3 < abs(taken_up(*placed_only).walk[1] - 1.5)


def test_a_carried_person_whose_walk_was_read_wrong_is_still_taken_up_near_where_they_were_left():
    """A young track's walk may be far off (feet jitter: 2 m/s read for somebody turning back at 0.5 m/s): found
    0.8 m from where they were left 0.6 s before, 2.0 m from where that walk led, they are still taken up (the reach
    holds from the place they were left as from where their walk led), not numbered anew."""
    from ray3d.site.events import CarriedPerson

    back = CAMERA.project(_walker((6.0, 0.75), (0.0, 0.5), 4))
    left = CarriedPerson("1-4", (6.0, 0.0), -0.5, 0.0, tracked=(6.0, 0.0, -0.5), walk=(0.0, -2.0))
    assert [t.id for t in _restarted([left], [[back[t]] for t in range(3)])] == ["1-4"]


def test_somebody_new_confirmed_first_beside_a_carried_person_does_not_take_their_id_from_them():
    """At a restart somebody new, seen a frame earlier, is confirmed first 0.6 m from where a carried person was
    left, within reach; the carried person, found again 0.05 m from there, is still being confirmed. The id goes
    by the likeliest assignment of both, not to whoever is confirmed first: the carried person keeps it."""
    from ray3d.site.events import CarriedPerson

    new = CAMERA.project(_walker((6.0, 0.6), (0.0, 0.0), 1))[0]
    back = CAMERA.project(_walker((6.05, 0.0), (0.0, 0.0), 1))[0]
    carried = [CarriedPerson("1-4", (6.0, 0.0), 0.0, 0.0, tracked=(6.0, 0.0, 0.0), walk=(0.0, 0.0))]
    tracks = _restarted(carried, [[new]] + [[new, back]] * 3)
    assert {t.id: t.frames[0] for t in tracks} == {"2-0": 0, "1-4": 1}


def test_a_stray_detection_of_an_earlier_frame_does_not_take_a_carried_persons_id():
    """A one-off detection right where a carried person was left, in the frame before somebody 0.3 m away is
    confirmed: only the people seen in the frame of the claim compete for the id, so the one confirmed takes it up."""
    from ray3d.site.events import CarriedPerson

    back = CAMERA.project(_walker((6.3, 0.0), (0.0, 0.0), 1))[0]
    stray = CAMERA.project(_walker((6.0, 0.0), (0.0, 0.0), 1))[0]
    carried = [CarriedPerson("1-4", (6.0, 0.0), 0.0, 0.0, tracked=(6.0, 0.0, 0.0), walk=(0.0, 0.0))]
    assert [(t.id, t.frames) for t in _restarted(carried, [[back], [back, stray], [back]])] == [("1-4", [0, 1, 2])]


def test_of_two_carried_people_near_somebody_found_the_one_in_their_clothes_is_taken_up():
    """Two people left 0.2 and 0.5 m from where somebody in blue is found: the nearer wore red, the other blue.
    The one in blue is taken up; nobody in clothes unlike theirs is, however near."""
    from ray3d.site.events import CarriedPerson

    def dressed(rgb) -> tuple:
        return tuple(clothes_colour(np.full((SIZE[1], SIZE[0], 3), rgb, np.uint8), np.array([0, 0, 50, 50]),
                                    np.array([0, 0, 50, 50])))

    blue = np.full((SIZE[1], SIZE[0], 3), (30, 60, 200), np.uint8)
    here = CAMERA.project(_walker((6.0, 0.0), (0.0, 0.0), 1))[0]
    in_red = CarriedPerson("1-4", (6.2, 0.0), 0.0, 0.0, tracked=(6.2, 0.0, 0.0), clothes=dressed((200, 30, 30)))
    in_blue = CarriedPerson("1-7", (6.0, 0.5), 0.0, 0.0, tracked=(6.0, 0.5, 0.0), clothes=dressed((30, 60, 200)))
    for carried, taken in (((in_red, in_blue), "1-7"), ((in_red,), "2-0")):
        assert [t.id for t in _restarted(carried, [[here]] * 3, blue)] == [taken]


def test_a_carried_person_far_away_is_reached_along_the_ray_as_far_as_the_floor_point_is_unsure_not_across_it():
    """20 m from a camera 3 m high, a floor point is unsure by about half a metre along the ray (a pixel is 0.3 m
    there) and little across it: a carried person left 1.4 m farther along the ray than where somebody is found is
    taken up; one left 1.4 m to the side is not (the reach alone, 1 m after 0.1 s, takes neither)."""
    from ray3d.site.events import CarriedPerson

    frame = np.full((SIZE[1], SIZE[0], 3), 60, np.uint8)
    far = CAMERA.project(_walker((20.0, 0.0), (0.0, 0.0), 1))[0]  # straight ahead: the ray runs along x
    found = FloorTracker(CAMERA, FPS, "h36m17", confirm_hits=3)
    for t in range(3):
        found.update(t, [Detection(far, np.ones(17), 0.9)], frame)
    measured = found.tracks()[0].floor[-1]  # where a tracker puts them (their ankles' rays meet the floor)
    for left_at, taken in ((measured + [1.4, 0.0], ["1-4"]), (measured + [0.0, 1.4], ["2-0"])):
        carried = [CarriedPerson("1-4", (30.0, 0.0), 0.0, 0.0, tracked=(*left_at, 0.0))]
        assert [t.id for t in _restarted(carried, [[far]] * 4)] == taken, left_at


def test_tracker_counts_dropped_frames_as_time_passing():
    """Live use drops frames: the filter moves people on for every frame since the last update, and a person
    unseen for longer than the gap in time (not in updates) has left."""
    walker = CAMERA.project(_walker((6.0, -2.0), (0.0, 2.0), 40))
    frame = np.full((SIZE[1], SIZE[0], 3), 60, np.uint8)
    tracker = FloorTracker(CAMERA, FPS, "h36m17", max_gap_s=0.25)  # 5 frames at 20 frames/s
    seen = list(range(10)) + list(range(14, 40, 4))  # every frame, then three in four dropped
    for t in seen:
        tracker.update(t, [Detection(walker[t], np.ones(17), 0.9)], frame)
    assert [t.frames for t in tracker.tracks()] == [seen]  # one person, followed across the drops
    tracker.update(46, [], frame)  # the next frame taken is 8 frames (0.4 s) later, with nobody
    assert [t.frames for t in tracker.finished()] == [seen]


def test_live_the_tracker_takes_a_person_up_again_as_it_goes_and_lets_them_go_only_after():
    """Live, where no later pass can re-join whole tracks: a walker hidden for 0.8 s (longer than the tracker
    waits) is taken up again where their walk led, under their own id, the frames between unseen; what was let go
    is handed over as finished only once nobody can take it up any more. Somebody starting across the room is
    somebody else; and without ``rejoin_s`` the walker comes back as a second person, as before."""
    walker = CAMERA.project(_walker((6.0, -2.0), (0.0, 1.2), 100))
    elsewhere = CAMERA.project(_walker((9.0, 3.0), (0.0, -1.2), 100))
    frame = np.full((SIZE[1], SIZE[0], 3), 60, np.uint8)
    seen = [t for t in range(100) if not 30 <= t < 46]
    for rejoin_s in (0.0, 3.0):
        tracker = FloorTracker(CAMERA, FPS, "h36m17", max_gap_s=0.25, rejoin_s=rejoin_s)
        finished = []
        for t in range(100 + 80):
            people = [Detection(walker[t], np.ones(17), 0.9)] if t in seen else []
            if rejoin_s and 40 <= t < 70:
                people.append(Detection(elsewhere[t], np.ones(17), 0.9))
            tracker.update(t, people, frame)
            finished += [(t, track) for track in tracker.finished()]
        if not rejoin_s:
            assert [track.frames for _, track in finished] == [seen[:30], seen[30:]]
            assert [track.id for _, track in finished] == ["0", "1"]
            continue
        (let_go_walker, walked), (let_go_other, other) = sorted(finished, key=lambda pair: pair[1].frames[0])
        assert walked.id == "0" and walked.frames == seen and len(walked.detections) == len(seen)
        (rejoin,) = walked.rejoins
        assert rejoin.identity == "0" and rejoin.after_frame == 29 and rejoin.gap_s == pytest.approx(17 / FPS)
        assert rejoin.miss_m < 0.5 and rejoin.unlike == pytest.approx(0.0, abs=1e-6)
        assert other.frames == list(range(40, 70)) and other.id not in ("0", rejoin.joined) and not other.rejoins
        # Handed over once a track starting after them could no longer be them: 3 s after their last frame.
        assert let_go_walker == 99 + int(3.0 * FPS) + 1 and let_go_other == 69 + int(3.0 * FPS) + 1


def test_the_detector_leaves_people_for_the_next_frame_only_when_time_is_short(monkeypatch):
    """Live use gives the detector the time it may take: the crops that do not fit are the last frame's people,
    smallest first, looked at first in the next frame (nobody is left out twice running); without a time
    every person is looked at in every frame."""
    import ray3d.video.detectors as detectors

    monkeypatch.setattr(detectors, "BlazePoseLandmarks", lambda threads: None)  # the network is not needed
    # The detector's clock stands still: the time before the crops (a busy machine's few hundred ms) leaves all
    # of ``time_left_s`` to them, so the room counted is the test's, not the machine's.
    monkeypatch.setattr(detectors, "time", SimpleNamespace(perf_counter=lambda: 0.0))
    detector = detectors.PeopleDetector(CAMERA)
    looked_at: list[list[float]] = []

    def look(frame, regions, vouched=None):  # everybody is where they were; a crop finds who it frames
        looked_at[-1] += [float(r[0]) for r in regions]
        corners = np.array([[-0.2, -0.4], [0.2, 0.4]])
        return [Detection(np.repeat(r[:2] + corners * r[2], [17, 16], axis=0), np.ones(33), 0.9, r.copy())
                for r in regions]

    detector._look = look
    people = np.array([[80.0 + 120 * k, 240.0, 60.0 + 10 * k, 0.0] for k in range(5)])  # larger to the right
    looked_at.append([])
    detector._previous = look(None, people)
    detector.crop_s = 0.1  # as measured: room for three crops
    frame = np.full((SIZE[1], SIZE[0], 3), 60, np.uint8)
    for _ in range(6):
        looked_at.append([])
        assert len(detector(frame, time_left_s=0.35)) == 3  # room for three crops
    rounds = [set(looked) for looked in looked_at[1:]]
    assert rounds[0] == {440.0, 560.0, 320.0}  # the largest three
    for before, after in zip(rounds, rounds[1:]):
        assert set(people[:, 0]) - before <= after  # left out once, looked at next
    assert detector.postponed == 12
    looked_at.append([])
    assert len(detector(frame)) == 5 and sorted(looked_at[-1]) == sorted(people[:, 0])  # no time given: all


def test_motion_where_nobody_was_found_for_a_while_is_looked_at_less_often_until_somebody_is(monkeypatch):
    """A car drives slowly through the picture: motion proposes it frame after frame and its crops find nobody.
    After ``EMPTY_RUN`` empty frames it is looked at only every ``EMPTY_EVERY``-th frame; a person walking out
    where it was is looked at within that many frames and followed (looked at in every frame) from then on. Without
    a finder to look in between, motion is looked at in every frame."""
    import ray3d.video.detectors as detectors

    monkeypatch.setattr(detectors, "BlazePoseLandmarks", lambda threads: None)
    feet, margin, person_from = np.array([400.0, 380.0]), 1.2, 20  # a crop holds somebody from frame 20 on
    tall = float(person_height_px(CAMERA, feet))

    def run(finder) -> tuple[list[int], list[int]]:
        """The frames in which the region was looked at, and the people found in each of 40 frames."""
        every = detectors.EMPTY_EVERY if finder is not None else 1  # as combined_detector and the people detector
        detector, looked = detectors.PeopleDetector(CAMERA, finder=finder, empty_every=every), []

        def network(frame, regions):
            index = int(frame[0, 0, 0])
            looked.extend([index] * len(regions))
            corners = np.array([[-0.2, -0.4], [0.2, 0.4]])
            pixels = np.array([np.repeat(r[:2] + corners * r[2] / margin, [17, 16], axis=0)
                               for r in regions]).reshape(-1, 33, 2)
            score = 0.9 if index >= person_from else 0.0
            return pixels, np.ones((len(regions), 33)), np.full(len(regions), score), regions.copy()

        detector._landmarks = network
        proposals = detector._proposals
        monkeypatch.setattr(proposals, "blobs", lambda frame: np.zeros((1, 4)))
        monkeypatch.setattr(proposals, "unexplained", lambda blobs, people: np.zeros((0, 4)))
        monkeypatch.setattr(proposals, "split_blobs", lambda blobs: np.array(  # moving slowly
            [[feet[0] + 2 * detector._frames_seen, feet[1] - tall / 2, margin * tall]]))
        found = [len(detector(np.full((SIZE[1], SIZE[0], 3), index, np.uint8))) for index in range(40)]
        return sorted(set(looked)), found

    nobody = SimpleNamespace(found=lambda frame: (np.zeros((0, 4)), np.zeros((0, 17, 3)), np.zeros(0)))
    looked, found = run(nobody)  # a finder that misses the person too
    empty_looks = [index for index in looked if index < person_from]
    assert empty_looks[:detectors.EMPTY_RUN] == list(range(detectors.EMPTY_RUN))
    later = empty_looks[detectors.EMPTY_RUN:]
    assert later and np.all(np.diff(later) == detectors.EMPTY_EVERY)  # every EMPTY_EVERY-th frame while empty
    first_seen = found.index(1)
    assert person_from <= first_seen < person_from + detectors.EMPTY_EVERY
    assert all(found[first_seen:]) and set(range(first_seen, 40)) <= set(looked)
    looked, found = run(None)
    assert looked == list(range(40)) and found.index(1) == person_from


def test_one_pose_stands_for_one_of_the_people_the_finder_found():
    """Two people the finder found, the one behind partly hidden, and one pose (both crops framed the one in
    front): the pose is the front person's, the one behind is not posed (the finder's keypoints stand in for them).
    Two poses for the two: both posed; no pose near a person: not posed."""
    from ray3d.video.boxes import whole_person
    from ray3d.video.detectors import UNPOSED_OVERLAP, posed_by

    front, behind, away = [100.0, 100.0, 160.0, 300.0], [112.0, 105.0, 170.0, 295.0], [400.0, 100.0, 460.0, 300.0]
    pose_of_front = [110.0, 120.0, 150.0, 290.0]  # the joints' box, inside the whole person's
    pose_of_behind = [120.0, 122.0, 162.0, 286.0]
    finder = np.array([front, behind, away])
    overlap = box_overlap(finder[:2], whole_person(np.array([pose_of_front])))[:, 0]
    assert (overlap >= UNPOSED_OVERLAP).all()  # either could be the pose's, by overlap alone
    assert posed_by(finder, np.array([pose_of_front])).tolist() == [True, False, False]
    assert posed_by(finder[::-1], np.array([pose_of_front])).tolist() == [False, False, True]
    assert posed_by(finder, np.array([pose_of_behind, pose_of_front])).tolist() == [True, True, False]


def test_person_height_follows_the_camera_geometry():
    near, far = person_height_px(CAMERA, [[320.0, 400.0], [320.0, 260.0]])
    assert near > far > 0
    floor = CAMERA.pixels_to_height_plane(np.array([320.0, 400.0]))
    head = CAMERA.project(floor + [0, 0, 1.7])
    assert near == pytest.approx(np.linalg.norm(head - CAMERA.project(floor)))
    assert np.isnan(person_height_px(CAMERA, [320.0, 0.0]))  # above the horizon: nobody stands there


def test_foreground_proposals_find_moving_people_and_split_a_pair():
    """Filled person-sized silhouettes moving over a textured background: one region per person, also for two
    walking side by side in one blob."""
    rng = np.random.default_rng(0)
    background = rng.integers(40, 120, (SIZE[1], SIZE[0], 3), dtype=np.uint8)
    feet = {"alone": np.array([150.0, 400.0]), "left": np.array([420.0, 330.0])}
    height = {k: float(person_height_px(CAMERA, v)) for k, v in feet.items()}

    def frame(shift):
        image = background.copy()
        for name, (u, v) in feet.items():
            h, w = height[name], 0.3 * height[name]
            columns = [u + shift] if name == "alone" else [u + shift, u + shift + 0.95 * w]
            for c in columns:
                cv2.rectangle(image, (int(c - w / 2), int(v - h)), (int(c + w / 2), int(v)), (230, 200, 30), -1)
        return image

    proposals = ForegroundProposals(CAMERA, median_background([background] * 5))
    regions = proposals(frame(0.0))
    assert len(regions) == 3
    for name, expected in (("alone", 1), ("left", 2)):
        u, v = feet[name]
        near = regions[np.abs(regions[:, 1] - (v - height[name] / 2)) < 0.25 * height[name]]
        assert len(near) == expected
        assert np.all(np.abs(near[:, 2] / height[name] - 1.35) < 0.3)  # crops sized for a person there


def test_a_person_the_bottom_edge_cuts_is_followed_and_flagged_in_part(tmp_path):
    """Walking towards the camera, their feet leave the picture in the last frames: one track all along, and
    the world file lists exactly the frames the detector put joints outside the picture."""
    walker = _walker((4.6, 0.0), (-1.0, 0.0))
    pixels = [CAMERA.project(walker)]
    path = _render(tmp_path / "near.mp4", pixels)
    result = lift_video(path, CAMERA, tmp_path / "out", StubDetector(pixels), Lifter.load(), overlay=False,
                        progress=False)
    world = read_world(result.files["world"])
    (name,) = world.tracks
    cut = np.flatnonzero((pixels[0][..., 1] >= SIZE[1]).any(axis=1) | (pixels[0] < 0).any(axis=(1, 2)))
    assert len(cut) >= 8 and len(world.tracks[name].frames) == FRAMES
    assert world.in_part == {name: cut.tolist()}
    jsonschema = pytest.importorskip("jsonschema")
    schema = json.loads(resources.files("ray3d").joinpath("assets", "world.schema.json").read_text())
    jsonschema.validate(json.loads(result.files["world"].read_text()), schema)
    document = json.loads(result.files["world"].read_text())
    (tmp_path / "odd.json").write_text(json.dumps({**document, "in_part": [3, 4]}))
    with pytest.raises(InputError, match="field in_part"):
        read_world(tmp_path / "odd.json")


def test_the_pipeline_refuses_what_it_cannot_use(scene, tmp_path):
    path, people, pixels, hidden = scene
    lifter = Lifter.load()
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "mine.txt").write_text("keep me")
    with pytest.raises(InputError, match="not empty"):
        lift_video(path, CAMERA, tmp_path / "full", StubDetector(pixels), lifter, overlay=False, progress=False)
    assert (tmp_path / "full" / "mine.txt").read_text() == "keep me"
    other = Camera.from_height_pitch(2.0, 15.0, (1280, 720), hfov_deg=70.0)
    with pytest.raises(InputError, match=r"image size \(1280, 720\) but .*640x480"):
        lift_video(path, other, tmp_path / "b", StubDetector(pixels), lifter, progress=False)
    with pytest.raises(InputError, match="nobody was found"):
        lift_video(path, CAMERA, tmp_path / "c", StubDetector([]), lifter, progress=False)
    with pytest.raises(InputError, match="nobody was found.* 1 frame"):  # one frame: too short to follow anybody
        lift_video(path, CAMERA, tmp_path / "one", StubDetector(pixels), lifter, video_options=VideoOptions(frames=1),
                   progress=False)
    with pytest.raises(InputError, match="start frame 99"):
        lift_video(path, CAMERA, tmp_path / "d", StubDetector(pixels), lifter, video_options=VideoOptions(start=99),
                   progress=False)
    with pytest.raises(InputError, match="frames must be at least 1"):
        VideoOptions(frames=0)
    with pytest.raises(InputError, match="max_gap_s must be a duration"):
        VideoOptions(max_gap_s=-1.0)
    (tmp_path / "notes.mp4").write_text("not a video")
    with pytest.raises(InputError, match="notes.mp4"):
        lift_video(tmp_path / "notes.mp4", CAMERA, tmp_path / "e", StubDetector(pixels), lifter, progress=False)
    cv2.VideoWriter(str(tmp_path / "empty.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), FPS, SIZE).release()
    with pytest.raises(InputError, match="empty.mp4"):
        lift_video(tmp_path / "empty.mp4", CAMERA, tmp_path / "f", StubDetector(pixels), lifter, progress=False)
    assert not any((tmp_path / name).exists() for name in "bcdef") and not (tmp_path / "one").exists()


def test_video_cli_tracks_everybody_with_a_registered_detector(scene, tmp_path, monkeypatch, capsys):
    path, people, pixels, hidden = scene
    monkeypatch.setitem(DETECTORS, "stub", lambda camera: StubDetector(pixels, hidden, start=4))
    common = ["--camera-height", "3", "--pitch", "15", "--hfov", "70", "--detector", "stub"]
    assert main(["video", str(path), *common, "--format", ".csv", "--out", str(tmp_path / "out"),
                 "--start", "4", "--frames", "30"]) == 0
    out = capsys.readouterr().out
    assert "30 frames, 3 people tracked" in out
    world = read_world(tmp_path / "out" / "world.csv")
    assert len(world.tracks) == 3 and min(int(t.frames[0]) for t in world.tracks.values()) == 4
    assert read_video_info(tmp_path / "out" / "overlay.mp4").frames == 30
    assert main(["video", str(path), *common[:-1], "yolo", "--out", str(tmp_path / "x")]) == 2
    assert "unknown detector 'yolo'" in capsys.readouterr().err
    assert main(["video", str(path), *common, "--out", str(tmp_path / "out")]) == 2
    assert "not empty" in capsys.readouterr().err
    assert main(["video", str(path), *common, "--out", str(tmp_path / "y"), "--min-track", "nan"]) == 2
    assert "(--min-track)" in capsys.readouterr().err
    assert main(["video", str(path), *common, "--format", ".bvh", "--no-overlay", "--out", str(tmp_path / "b"),
                 "--start", "4", "--frames", "30"]) == 0
    listed = [line.split()[-1] for line in capsys.readouterr().out.splitlines() if line.strip().startswith("world ")]
    assert len(listed) == 3 and sorted(listed) == sorted(str(p) for p in (tmp_path / "b").glob("world_*.bvh"))
    assert main(["video", str(path), *common, "--format", ".trc", "--frame", "camera", "--out",
                 str(tmp_path / "c")]) == 2 and not (tmp_path / "c").exists()
    assert "world frame" in capsys.readouterr().err


def test_landmark_network_on_crops():
    pytest.importorskip("ai_edge_litert", reason="the video extra is not installed: pip install 'ray3d[video]'")
    from ray3d.video.landmarks import BlazePoseLandmarks, crop_transforms

    regions = np.array([[100.0, 200.0, 128.0], [400.0, 300.0, 512.0], [10.0, 10.0, 64.0]])
    maps = crop_transforms(regions)
    for region, m in zip(regions, maps):  # each region's centre maps to the crop's centre, its side to 256 px
        np.testing.assert_allclose(m @ [region[0], region[1], 1.0], [128.0, 128.0])
        np.testing.assert_allclose(m[0, 0] * region[2], 256.0)
    landmarks = BlazePoseLandmarks(threads=1)
    frame = np.full((SIZE[1], SIZE[0], 3), 90, np.uint8)
    pixels, confidences, scores, following = landmarks(frame, regions)
    assert pixels.shape == (3, 33, 2) and confidences.shape == (3, 33) and scores.shape == (3,)
    assert following.shape == (3, 4)
    assert np.all(scores < 0.5)  # nobody in a flat grey frame
    assert all(len(x) == 0 for x in landmarks(frame, np.zeros((0, 3))))


def test_mediapipe_detector_finds_nobody_in_an_empty_frame():
    pytest.importorskip("mediapipe", reason="the video extra is not installed: pip install 'ray3d[video]'")
    from ray3d.video import MediaPipeDetector

    detector = MediaPipeDetector()
    assert detector(np.full((SIZE[1], SIZE[0], 3), 60, np.uint8)) == []
    detector.close()


def test_the_real_chain_finds_and_follows_two_people_in_a_generated_video(tmp_path):
    """Two figures (matplotlib's sample portrait of Grace Hopper over a dark coat, which the landmark network
    takes for a person) walking past each other over a textured background: foreground proposals, landmarks on
    the crops, tracking and lifting run for real and give one track per figure, each staying on its figure."""
    pytest.importorskip("ai_edge_litert", reason="the video extra is not installed: pip install 'ray3d[video]'")
    import matplotlib

    from ray3d.video import PeopleDetector

    portrait = cv2.imread(str(Path(matplotlib.get_data_path()) / "sample_data" / "grace_hopper.jpg"))
    figure, drawn = np.zeros((170, 68, 3), np.uint8), np.zeros((170, 68), dtype=bool)
    figure[:80], drawn[:80] = cv2.resize(portrait, (68, 80)), True
    figure[80:, 10:58], drawn[80:, 10:58] = (40, 35, 30), True  # the coat
    camera = Camera.from_height_pitch(5.0, 20.0, SIZE, hfov_deg=30.0)  # a person standing at row 350 is 166 px
    rng = np.random.default_rng(1)
    background = cv2.GaussianBlur(rng.integers(70, 150, (SIZE[1], SIZE[0], 3), dtype=np.uint8), (5, 5), 0)
    frames, centre = 30, {}
    writer = cv2.VideoWriter(str(tmp_path / "two.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), FPS, SIZE)
    for t in range(frames):
        image = background.copy()
        for person, (row, start, step) in enumerate(((170, 60, 12), (190, 470, -11))):  # they cross at frame 12
            column = start + step * t
            image[row:row + 170, column:column + 68][drawn] = figure[drawn]
            centre[(person, t)] = column + 34
        writer.write(image)
    writer.release()
    result = lift_video(tmp_path / "two.mp4", camera, tmp_path / "out", PeopleDetector(camera, threads=1),
                        Lifter.load(), video_options=VideoOptions(min_track_s=0.5), overlay=False, progress=False)
    assert len(result.world.tracks) == 2
    for track, (seen, pixels, confidences) in result.keypoints.by_track().items():
        nose = pixels[:, 0, 0]  # BlazePose's first landmark: on one figure all along
        person = int(np.argmin([abs(nose[0] - centre[(p, int(seen[0]))]) for p in (0, 1)]))
        assert len(seen) >= 0.7 * frames
        assert all(abs(u - centre[(person, int(f))]) < 30 for u, f in zip(nose, seen))


def _portrait_figure(height: int):
    """A figure the person detectors take for a person: matplotlib's sample portrait of Grace Hopper over a dark
    coat, ``height`` pixels tall; (image, mask of its drawn pixels)."""
    import matplotlib

    portrait = cv2.imread(str(Path(matplotlib.get_data_path()) / "sample_data" / "grace_hopper.jpg"))
    width, head = int(0.4 * height), int(height * 80 / 170)
    figure, drawn = np.zeros((height, width, 3), np.uint8), np.zeros((height, width), dtype=bool)
    figure[:head], drawn[:head] = cv2.resize(portrait, (width, head)), True
    margin = int(width * 10 / 68)
    figure[head:, margin:width - margin], drawn[head:, margin:width - margin] = (40, 35, 30), True
    return figure, drawn


def _still_figure_video(path: Path, height: int, top_left: tuple[int, int], sway_px: int = 0, frames: int = FRAMES):
    figure, drawn = _portrait_figure(height)
    background = cv2.GaussianBlur(np.random.default_rng(1).integers(70, 150, (SIZE[1], SIZE[0], 3), dtype=np.uint8),
                                  (5, 5), 0)
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), FPS, SIZE)
    for t in range(frames):
        image = background.copy()
        row, column = top_left[0], top_left[1] + int(round(sway_px * np.sin(t / 3)))
        image[row:row + height, column:column + figure.shape[1]][drawn] = figure[drawn]
        writer.write(image)
    writer.release()
    return path


@pytest.mark.parametrize("height, top_left, sway", [(420, (30, 270), 0),      # stands still all along
                                                    (450, (15, 250), 3)])     # fills the frame, swaying
def test_the_default_finder_follows_a_still_or_frame_filling_person_as_one_track(tmp_path, height, top_left, sway):
    pytest.importorskip("ai_edge_litert", reason="the video extra is not installed: pip install 'ray3d[video]'")
    from ray3d.video import DEFAULT_DETECTOR, make_detector, track_video

    camera = Camera.from_height_pitch(1.6, 5.0, SIZE, hfov_deg=60.0)
    video = _still_figure_video(tmp_path / "still.mp4", height, top_left, sway)
    assert DEFAULT_DETECTOR == "combined"
    people = track_video(video, camera, make_detector(DEFAULT_DETECTOR, camera), VideoOptions(), progress=False)
    assert len(people.tracks) == 1 and people.detector == "combined"
    (track,) = people.tracks.values()
    assert len(track.frames) >= 0.95 * FRAMES
    if not sway:  # motion alone never sees a person who does not move
        with pytest.raises(InputError, match="nobody was found"):
            track_video(video, camera, make_detector("people", camera), VideoOptions(), progress=False)


def test_a_short_clip_keeps_a_person_seen_all_along(tmp_path):
    from ray3d.video import track_video

    frames = 16  # 0.8 s: shorter than the default minimum track of 1 s
    pixels = [CAMERA.project(_walker((6.0, 0.0), (0.0, 0.5)))]
    path = _render(tmp_path / "short.mp4", pixels)
    people = track_video(path, CAMERA, StubDetector(pixels), VideoOptions(frames=frames), progress=False)
    assert [len(t.frames) for t in people.tracks.values()] == [frames]


def test_nobody_kept_says_what_was_found_and_what_would_keep_it(tmp_path):
    from ray3d.video import track_video

    pixels = [CAMERA.project(_walker((6.0, 0.0), (0.0, 0.5)))]
    seen = set(range(10, 20))  # 0.5 s of a 2 s clip
    path = _render(tmp_path / "glimpse.mp4", pixels, {(0, t) for t in range(FRAMES) if t not in seen})
    with pytest.raises(InputError, match=r"1 candidate track\(s\), the longest seen for 0\.50 s; a minimum track "
                                         r"length of 0\.50 s would keep it") as caught:
        track_video(path, CAMERA, StubDetector(pixels, {(0, t) for t in range(FRAMES) if t not in seen}),
                    VideoOptions(), progress=False)
    assert caught.value.arguments == ("min_track_s",)
    with pytest.raises(InputError, match="found nobody in any frame") as caught:
        track_video(path, CAMERA, StubDetector([]), VideoOptions(), progress=False)
    assert caught.value.arguments == ("detector",)
    people = track_video(path, CAMERA, StubDetector(pixels, {(0, t) for t in range(FRAMES) if t not in seen}),
                         VideoOptions(min_track_s=0.5), progress=False)
    assert len(people.tracks) == 1


def test_landmarks_move_to_the_heatmap_peak_only_where_the_heatmap_is_sure():
    from ray3d.video.landmarks import INPUT_SIZE, refine_from_heatmap

    heatmaps = np.full((1, 64, 64, 3), -10.0)
    heatmaps[0, 20, 31, 0] = 10.0            # a sure peak beside landmark 0
    heatmaps[0, 40, 10, 1] = -1.0            # landmark 1: nothing above 0.5 near it
    points = np.array([[[30.5, 21.5], [10.5, 40.5], [-40.0, 10.0]]]) * INPUT_SIZE / 64  # landmark 2: outside
    refined = refine_from_heatmap(points, heatmaps)
    np.testing.assert_allclose(refined[0, 0], np.array([31, 20]) * INPUT_SIZE / 64, atol=0.05)
    np.testing.assert_array_equal(refined[0, 1:], points[0, 1:])


def test_upright_crops_map_the_body_axis_to_the_crop_vertical():
    from ray3d.video.landmarks import INPUT_SIZE, crop_transforms, upright_rotation

    hips, up = np.array([[300.0, 400.0]]), np.array([[1.0, -1.0]]) / np.sqrt(2)  # a body leaning 45 degrees right
    rotation = upright_rotation(hips, hips + 100 * up)
    (m,) = crop_transforms(np.array([[*hips[0], 256.0, rotation[0]]]))
    head = m @ [*(hips[0] + 100 * up[0]), 1.0]
    np.testing.assert_allclose(m @ [*hips[0], 1.0], [INPUT_SIZE / 2, INPUT_SIZE / 2], atol=1e-9)
    np.testing.assert_allclose(head, [INPUT_SIZE / 2, INPUT_SIZE / 2 - 100], atol=1e-9)
    assert upright_rotation(hips, hips + [[0.0, -50.0]])[0] == pytest.approx(0.0)


def test_two_videos_of_one_site_are_lifted_on_one_floor_found_where_both_see_people(scene, tmp_path, monkeypatch,
                                                                                    capsys):
    """``lift_videos``: the same walk filmed from the front and the side (frames in step), each followed as
    ``lift_video`` follows it, lifted together: one ankle plane for both, their ankles triangulated where both see
    a person, close to where the mocap's planted ankles stand over the floor; each video's outputs written."""
    from ray3d.geometry.intrinsics import focal_from_hfov
    from ray3d.video import lift_videos

    _, people, pixels, hidden = scene
    focal = focal_from_hfov(SIZE[0], 70.0)
    side = Camera.from_pose([7.0, -11.0, 4.0], np.pi / 2, np.radians(14.0), 0.0, focal, focal, 320.0, 240.0, SIZE)
    side_pixels = [side.project(p) for p in people]
    side_video = _render(tmp_path / "side.mp4", side_pixels)
    front_video = _render(tmp_path / "front.mp4", pixels, hidden)
    results = lift_videos([(front_video, CAMERA, tmp_path / "front", StubDetector(pixels, hidden)),
                           (side_video, side, tmp_path / "side", StubDetector(side_pixels))], Lifter.load(),
                          progress=False)
    planes = [next(iter(r.world.tracks.values())).refinement["ankle_plane"] for r in results]
    assert planes[0] == planes[1] and planes[0]["seen_twice"] == 3
    assert planes[0]["floor_z_m"] == pytest.approx(0.0, abs=0.03) and planes[0]["sd_m"] < 0.03
    assert all(r.files["world"].is_file() and r.files["overlay"].is_file() for r in results)
    alone = lift_video(front_video, CAMERA, tmp_path / "alone", StubDetector(pixels, hidden), Lifter.load(),
                       progress=False)
    assert next(iter(alone.world.tracks.values())).refinement["ankle_plane"]["seen_twice"] == 0
    # The command line: ray3d video with both videos and their cameras says so, and fuses one world.
    monkeypatch.setitem(DETECTORS, "stub", lambda camera: StubDetector(
        side_pixels if camera.name == "side" else pixels, () if camera.name == "side" else hidden))
    cameras = []
    for name, camera in (("front", CAMERA), ("side", side)):
        cameras += ["--camera", str(tmp_path / f"{name}.json")]
        (tmp_path / f"{name}.json").write_text(json.dumps({**camera.to_dict(), "name": name}))
    assert main(["video", str(front_video), str(side_video), *cameras, "--detector", "stub",
                 "--out", str(tmp_path / "site")]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if "floor" in line and "people" in line]
    assert len(notes) == 2 and all("3 by two cameras at once" in line for line in notes)
    assert len(read_world(tmp_path / "site" / "world.json").tracks) == 3
