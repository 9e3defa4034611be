"""Live: the frame source's dropping, stalling and ending; causal lifting whose final answer is the offline one;
the site's events as they happen equal to the report's; the page's endpoints; the webhook; the world file read
while it grows; signals."""

from __future__ import annotations

import json
import threading
import time
import types

import numpy as np
import pytest
from browser import needs_chromium, screenshot

from ray3d import InputError, cameras
from ray3d.demo import demo_clip
from ray3d.io.world import LiftResult, World, append_world_csv, read_world
from ray3d.lifting.options import VideoOptions
from ray3d.live.source import FrameSource, SourceGroup, StreamStalled
from ray3d.site import CountingLine, Site, SiteMonitor, Zone, line_crossings, site_events

CAMERA = cameras.h36m("S9", "54138969")
FPS = 10.0


def _ground_axes() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A spot on the floor 5 m in front of the camera, the camera's horizontal viewing direction there and the
    direction across the image (people walk along it)."""
    looking = CAMERA.pixels_to_world_directions(np.array([[512.0, 515.0]]))[0][:2]
    looking /= np.linalg.norm(looking)
    across = np.array([looking[1], -looking[0]])
    return CAMERA.center[:2] + 5.0 * looking, looking, across


SPOT, LOOKING, ACROSS = _ground_axes()
DOOR = CountingLine("door", SPOT + 0.5 * ACROSS - 3 * LOOKING, SPOT + 0.5 * ACROSS + 3 * LOOKING)
ROOM = Zone("room", np.array([SPOT + a * ACROSS + b * LOOKING for a, b in ((1, -3), (4, -3), (4, 3), (1, 3))]))


def _scene(frames: int = 40) -> np.ndarray:
    """Two people walking across the door line in opposite directions, 2 m apart, at 10 frames/s:
    (frames, 2, 17, 3) world joints."""
    clip = demo_clip()[::6]
    clip = clip[np.arange(frames) % len(clip)]
    clip = clip - clip[:, :1] * [1, 1, 0]  # walking on the spot; the walks below move them
    walk = np.linspace(-1.2, 1.2, frames)[:, None] * ACROSS
    one = clip + np.concatenate([SPOT + walk - 1.0 * LOOKING, np.zeros((frames, 1))], axis=1)[:, None]
    two = clip + np.concatenate([SPOT - walk + 1.0 * LOOKING, np.zeros((frames, 1))], axis=1)[:, None]
    return np.stack([one, two], axis=1)


class _ScriptedDetector:
    """A detector that finds, frame after frame, the scene's people where the camera sees them."""

    layout = "h36m17"
    name = "scripted"

    def __init__(self, people: np.ndarray, camera=CAMERA):
        self.pixels = camera.project(people)  # (T, P, 17, 2)
        self.calls: list[int] = []  # the frames it looked at
        self.time_left: list[float | None] = []  # the time it was given for each
        self.unseen: set[tuple[int, int]] = set()  # (frame, person) it does not find

    def prepare(self, frames) -> None:
        pass

    def __call__(self, frame, time_left_s=None):
        from ray3d.video.detectors import Detection

        index = int(frame[0, 0, 0]) + 256 * int(frame[0, 0, 1])  # the frame carries its own number
        self.calls.append(index)
        self.time_left.append(time_left_s)
        return [Detection(p, np.ones(17), 0.9) for k, p in enumerate(self.pixels[index])
                if (index, k) not in self.unseen]


CLOTHES = ((200, 40, 40), (40, 60, 200))


def _frames(count: int, sleep_s: float = 0.0, stall_after: int | None = None, stall_s: float = 0.0,
            people: np.ndarray | None = None, camera=CAMERA):
    """Frames carrying their number in the first pixel; with ``people``, the camera's full picture with each
    person's torso painted in their own colour (what the tracker tells clothes by)."""
    import cv2

    pixels = None if people is None else camera.project(people)
    for index in range(count):
        if stall_after is not None and index == stall_after:
            time.sleep(stall_s)
        if pixels is None:
            image = np.zeros((8, 8, 3), np.uint8)
        else:
            image = np.full((camera.image_size[1], camera.image_size[0], 3), 128, np.uint8)
            for person, colour in zip(pixels[index], CLOTHES):
                torso = person[[1, 4, 11, 14]]
                cv2.rectangle(image, tuple(int(v) for v in torso.min(0) - 8), tuple(int(v) for v in torso.max(0) + 8),
                              colour, -1)
        image[0, 0, :2] = index % 256, index // 256
        yield image
        time.sleep(sleep_s)


def test_a_slow_reader_gets_the_newest_frame_and_the_rest_are_dropped_and_counted():
    source = FrameSource(_frames(60, sleep_s=0.002), 100.0, "test", paced=False)
    taken = []
    while (frame := source.next()) is not None:
        taken.append(frame.index)
        time.sleep(0.03)
    assert source.read == 60 and source.dropped > 20
    assert len(taken) + source.dropped == 60  # every frame either taken or counted as dropped
    assert taken == sorted(taken) and len(set(taken)) == len(taken)


def test_a_source_asked_for_every_third_frame_keeps_those_and_counts_the_rest_as_skipped_not_dropped():
    source = FrameSource(_frames(30), 100.0, "test", waits=True, stride=3)
    taken = []
    while (frame := source.next()) is not None:
        taken.append(frame.index)
        if frame.index == 15:
            source.stride = 5  # asked for fewer on the way
    assert taken == [0, 3, 6, 9, 12, 15, 20, 25] or taken == [0, 3, 6, 9, 12, 15, 18, 20, 25]  # 18: read already
    assert source.read == 30 and source.dropped == 0 and source.skipped == 30 - len(taken)


def test_files_read_as_fast_as_processed_are_taken_in_the_order_of_their_times_however_late_one_is_read():
    """Several cameras' files that wait for their reader are taken in the order of their frames' times (on the
    first camera's clock, ``offsets_s``), not of when a busy machine's threads read them: one camera's frames never
    run ahead of another's, so the join of their people is the same every time."""
    for offsets_s in ([0.0, 0.0], [0.0, 0.25]):
        late = FrameSource(_frames(6, stall_after=2, stall_s=0.3), FPS, "late", waits=True)  # its reader held up
        group = SourceGroup([late, FrameSource(_frames(6), FPS, "on time", waits=True)])
        group.offsets_s = offsets_s
        taken = [(view, frame.index) for view, frame in iter(group.next, None)]
        assert taken == sorted(((v, k) for v in (0, 1) for k in range(6)), key=lambda f: (f[1] / FPS - offsets_s[f[0]],
                                                                                           f[0]))


class _Answer:
    """A step's answer on ``_StepsOnAClock``: ``value`` once the virtual clock reaches ``at``."""

    def __init__(self, at: float, value):
        self.at, self.value = at, value


class _StepsOnAClock:
    """A stand-in for Ray as ``RayCameras`` calls it: each actor a scripted camera whose every step takes
    ``step_s`` of a virtual clock (``ray.wait`` gives the step finished first on it), answering frames 0 ..
    ``frames`` - 1 and then its stream's end."""

    class exceptions:
        class RayError(Exception):
            pass

        class RayActorError(RayError):
            pass

    def __init__(self):
        self.now = 0.0

    def remote(self, **_):
        clock = self

        class Actor:
            def __init__(self, frames=0, step_s=1.0, fps=FPS, name="", floor=None, **_):
                self.frames, self.step_s, self.fps, self.name, self.taken = frames, step_s, fps, name, 0
                self.describe = self._call(lambda: (CAMERA, self.fps, self.name))
                self.step = self._call(self._step, self.step_s)
                self.finish = self._call(lambda: ([], []))
                self.close_source = self._call(lambda: None)

            def _step(self):
                from ray3d.live.cameras import FrameResult

                if self.taken == self.frames:
                    return "ended", f"{self.name}: the stream ended"
                self.taken += 1
                return FrameResult(self.taken - 1, time.monotonic(), [], [], [])

            def _call(self, answer, takes_s=0.0):
                return types.SimpleNamespace(remote=lambda *a: _Answer(clock.now + takes_s, answer()))

        return lambda cls: types.SimpleNamespace(remote=lambda **arguments: Actor(**arguments))

    def wait(self, refs, num_returns=1, timeout=None):
        first = min(refs, key=lambda ref: ref.at)
        self.now = max(self.now, first.at)
        return [first], [ref for ref in refs if ref is not first]

    def get(self, ref):
        return ref.value

    def kill(self, actor):
        pass


@pytest.mark.parametrize("played", [False, True])
def test_on_ray_files_read_as_fast_as_processed_are_taken_in_the_order_of_their_times_however_quick_an_actor(
        played):
    """On Ray one camera's actor may answer three times as fast as another's: where both read their files as fast
    as they are processed, their frames are still taken in the order of their times (on the first camera's clock),
    so their people are joined at the moments they were seen; played streams are taken as they come."""
    from ray3d.live.cluster import RayCameras

    arguments = [{"frames": 6, "step_s": 3.0, "name": "slow"}, {"frames": 6, "step_s": 1.0, "name": "quick"}]
    cameras = RayCameras(_StepsOnAClock(), arguments, ["slow.avi", "quick.avi"], [played, played])
    cameras.set_clocks([0.0, 0.25])
    taken = [(view, result.index) for view, result in iter(cameras.next, None)]
    in_time = sorted(((v, k) for v in (0, 1) for k in range(6)), key=lambda f: (f[1] / FPS - [0.0, 0.25][f[0]], f[0]))
    assert sorted(taken) == sorted(in_time)  # every frame once
    assert (taken == in_time) is not played
    assert len(cameras.finish()) == 2


def test_under_load_a_camera_takes_every_kth_frame_and_every_frame_again_once_the_work_fits():
    from ray3d.live.people import MOST_FRAMES_APART, PACE_WARM_UP, Pacing

    pacing = Pacing(10.0)
    assert [pacing.observe(1.0) for _ in range(PACE_WARM_UP)] == [1] * PACE_WARM_UP  # the networks' first calls
    busy = [pacing.observe(0.25) for _ in range(40)]  # each taken frame's work: 2.5 frame intervals
    assert busy == [3] * 40
    fits = [pacing.observe(0.05) for _ in range(60)]  # half an interval again
    assert fits == sorted(fits, reverse=True) and fits[-1] == 1 and 2 in fits  # one step at a time
    assert Pacing(10.0).observe(0.25) == 1
    near = Pacing(10.0)
    for work in [0.05] * PACE_WARM_UP + [0.12] * 30 + [0.09] * 100:  # over the interval, then at 0.9 of it
        near.observe(work)
    assert near.stride == 2  # back to every frame only with a margin: no flapping at the edge
    swamped = Pacing(10.0)
    for _ in range(PACE_WARM_UP + 5):
        swamped.observe(5.0)
    assert swamped.stride == MOST_FRAMES_APART


def test_a_file_plays_at_its_own_rate_and_then_ends():
    source = FrameSource(_frames(6), 20.0, "test", paced=True)
    start = time.monotonic()
    taken = [frame.index for frame in iter(source.next, None)]
    assert taken == list(range(6)) and source.dropped == 0
    assert 0.2 <= time.monotonic() - start < 1.5  # 6 frames at 20 frames/s: 0.25 s


def test_a_stalled_stream_is_reported_after_its_timeout_with_what_came_before_kept():
    source = FrameSource(_frames(10, stall_after=3, stall_s=2.0), 50.0, "camera 7", paced=False, stall_s=0.3)
    taken = []
    with pytest.raises(StreamStalled, match="camera 7: no frame for 0.3 s"):
        while True:
            time.sleep(0.05)  # slower than the frames: the slot holds the newest
            taken.append(source.next().index)
    assert taken and taken[-1] == 2
    source.close()


def test_a_file_taken_up_past_its_end_says_nothing_is_left_not_that_it_is_not_a_video(tmp_path):
    """A store's record may take a file up where an earlier run left it; where that run had taken every frame, the
    refusal says so (a restart after the file ended), not that the file is no video."""
    import cv2

    path = tmp_path / "five.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (64, 48))
    for k in range(5):
        writer.write(np.full((48, 64, 3), 40 * k, np.uint8))
    writer.release()
    assert FrameSource.open(path, first_index=4).next().index == 4
    for first in (5, 9):
        with pytest.raises(InputError, match=r"five.avi: nothing left to follow: its 5 frames were all taken by an "
                                             rf"earlier run \(the store's record takes it up at frame {first}\)"):
            FrameSource.open(path, first_index=first)


def test_what_is_not_a_video_is_refused_in_one_line(tmp_path, capsys):
    from ray3d.cli import main

    text = tmp_path / "notes.txt"
    text.write_text("not a video")
    with pytest.raises(InputError, match="notes.txt: (cannot be opened|no frame could be read)"):
        FrameSource.open(text)
    assert main(["live", str(text), "--camera", "h36m:S9:54138969", "--out", str(tmp_path / "out")]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
    assert main(["live", str(text), str(text), "--camera", "h36m:S9:54138969", "--out", str(tmp_path / "out")]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        "ray3d live: error: --camera: 1 given for 2 sources; give one per source, in order"]


def _run(tmp_path, people: np.ndarray, site: Site = Site(), fps: float = 20.0, detector=None, **options):
    """A live job over the scene's frames (each carrying its number), played at ``fps`` (a fast replay), the
    people found by ``detector`` (default: where the camera sees them)."""
    from ray3d.jobs import CameraChoice, Job
    from ray3d.jobs.live import live_job, local_inputs
    from ray3d.live.runner import LiveOptions

    job = Job(("scene",), (CameraChoice(made=CAMERA),), video=VideoOptions(min_track_s=0.5))
    lifter = job.lifter("h36m17")  # before the stream starts: frames that come while it loads would be dropped
    lifter.prepare_small_batches()  # and so would those while it traces its small-batch path
    detector = detector or _ScriptedDetector(people)
    source = FrameSource(_frames(len(people), people=people), fps, "scene", paced=True)
    live_options = LiveOptions(**{"page": False, **options})
    run = live_job(job, tmp_path / "live", live_options, site=site,
                   streams=lambda job, recorder: local_inputs(job, SourceGroup([source]), [CAMERA], [detector]))
    return run.summary, detector


def _one_camera(people: np.ndarray, fps: float, name: str = "scene", stall_timeout_s: float = 5.0, **frames):
    """A live job of one camera over the scene's frames (``frames``: how ``_frames`` makes them) played at ``fps``
    (no frame for ``stall_timeout_s``: stalled), its model loaded already: the job, the frames' source and how the job
    opens it (``live_job``'s ``streams``), the people found where the camera sees them."""
    from ray3d.jobs import CameraChoice, Job
    from ray3d.jobs.live import local_inputs

    job = Job((name,), (CameraChoice(made=CAMERA),), video=VideoOptions(min_track_s=0.5))
    job.lifter("h36m17")  # before the stream starts: frames that come while it loads would be dropped
    source = FrameSource(_frames(len(people), people=people, **frames), fps, name, paced=True,
                         stall_s=stall_timeout_s)

    def opened(job, recorder):
        return local_inputs(job, SourceGroup([source]), [CAMERA], [_ScriptedDetector(people)])

    return job, source, opened


def test_the_final_world_is_the_offline_answer_and_the_live_answer_is_close_to_it(tmp_path):
    from ray3d.lifting.lifter import Lifter
    from ray3d.lifting.options import LiftOptions
    from ray3d.live.people import LivePeople
    from ray3d.live.source import LiveFrame

    people = _scene()
    detector = _ScriptedDetector(people)
    lifter = Lifter.load()
    live = LivePeople(CAMERA, detector, lifter, FPS)
    answers: dict[int, list] = {}
    for index, image in enumerate(_frames(len(people), people=people)):
        now, _ = live.update(LiveFrame(index, image, time.monotonic()))
        for person in now:
            answers.setdefault(person.track, []).append((index, person.joints))
    tracks = live.in_view()
    assert len(tracks) == 2 and all(len(t.frames) == len(people) for t in tracks)
    for track in tracks:
        offline = lifter.lift_tracks({track.id: track.as_detections()}, CAMERA, "h36m17", FPS,
                                     **LiftOptions().lift_arguments())[track.id]
        truth = people[:, np.argmin([np.linalg.norm(people[0, p, 0] - offline.root[0]) for p in range(2)])]
        frames = np.array([f for f, _ in answers[track.id]])
        causal = np.stack([j for _, j in answers[track.id]])
        # Live answers from the frame a track is confirmed (its third detection) on, each at once.
        assert frames[0] == 2 and np.array_equal(frames, np.arange(2, len(people)))
        causal_error = np.linalg.norm(causal[:, 0, :2] - truth[frames, 0, :2], axis=-1)
        offline_error = np.linalg.norm(offline.root[:, :2] - truth[:, 0, :2], axis=-1)
        assert np.median(offline_error) < 0.15 and np.median(causal_error) < 0.3
    # The refinement at a track's end, on its whole history, is the offline refinement of those joints.
    from ray3d.refine import refine_track

    following = live._following[tracks[0].id]
    raw = np.stack([j for _, j in following.history])
    live.close()  # the refinement under way (on its own thread) done
    live._refine(following, raw)
    _, offline_refinement = refine_track(raw, CAMERA, FPS, config=live.config)
    assert following.scale == pytest.approx(offline_refinement.scale[-1], abs=1e-12)


def test_a_person_standing_by_a_zone_edge_with_a_jittery_detector_does_not_flicker_in_and_out_live(tmp_path):
    """Somebody standing 0.15 m inside the room, their detections jumping about 25 px sideways frame to frame (about
    0.1 m on the floor): the live answers are smoothed causally (One-Euro, ``live.people.LIVE_SMOOTHING``), so
    the live events have them in the room throughout, not entering and leaving it frame by frame (unsmoothed: 16
    zone events in 3 s)."""
    clip = demo_clip()[::6][:1] - demo_clip()[::6][:1, :1] * [1, 1, 0]
    people = (clip + np.append(SPOT + 1.15 * ACROSS, 0.0))[None].repeat(60, axis=0)  # (60, 1, 17, 3)
    detector = _ScriptedDetector(people)
    detector.pixels = detector.pixels + np.random.default_rng(0).normal(0, 25, (60, 1, 1, 1)) * [1, 0]
    summary, _ = _run(tmp_path, people, Site((ROOM,), ()), detector=detector)
    events = [json.loads(line) for line in (tmp_path / "live" / "events.jsonl").read_text().splitlines()]
    assert summary.processed > 40 and [e["event"] for e in events if e["event"].startswith("zone")] == []
    assert events[0]["event"] == "track started" and ROOM.contains(np.array([events[0]["place_m"][:2]]))[0]


def test_the_detector_is_given_the_time_until_the_frame_is_due_and_a_person_unseen_once_is_held(monkeypatch):
    import ray3d.live.people as live_people
    from ray3d.lifting.lifter import Lifter
    from ray3d.live.people import RUNNER_SHARE, LivePeople
    from ray3d.live.source import LiveFrame

    # The runner's clock stands still (the frames' arrivals are stamped by it too): the time a busy machine takes
    # to lift a frame does not eat into the time the test gives the detector.
    monkeypatch.setattr(live_people, "time", types.SimpleNamespace(monotonic=lambda: 100.0))

    people = _scene(12)
    detector = _ScriptedDetector(people)
    detector.unseen = {(8, 0)}  # the first person is not found in frame 8 (left for the next frame, say)
    live = LivePeople(CAMERA, detector, Lifter.load(), FPS, deadline_frames=2)
    images = list(_frames(len(people), people=people))
    answers = []
    for index, image in enumerate(images):
        late = 0.15 if index == 5 else 0.0  # frame 5 waited 0.15 s before it was taken
        answers.append(live.update(LiveFrame(index, image, 100.0 - late))[0])
    live.close()
    on_time, waited = detector.time_left[4], detector.time_left[5]
    assert on_time == pytest.approx(2 / FPS - RUNNER_SHARE / FPS)  # two frames' time less the runner's share
    assert waited == pytest.approx(on_time - 0.15)
    held = {p.track: p for p in answers[7]}
    assert len(answers[8]) == 2  # both still there: one seen, one at their place of frame 7
    unseen = [p for p in answers[8] if p.track in held and np.array_equal(p.joints, held[p.track].joints)]
    assert len(unseen) == 1
    track = next(t for t in live.in_view() if t.id == unseen[0].track)
    assert 8 not in track.frames and {7, 9} <= set(track.frames)  # the world track has only what was seen


def test_a_person_hidden_for_a_second_keeps_their_id_live_and_is_counted_once():
    """The first person is not found for 1 s (twice the tracker's gap): found again where their walk led, in
    their clothes, they are taken up under their own id (``rejoin_s``, the default): one "track started" each,
    no "track ended" until the stream ends, their track's frames with the gap unseen and its re-join. With
    ``rejoin_s`` 0 they come back as a third person, their first track let go during the gap."""
    from ray3d.lifting.lifter import Lifter
    from ray3d.live.people import LivePeople
    from ray3d.live.source import LiveFrame

    people = _scene(50)
    hidden = set(range(15, 25))
    lifter = Lifter.load()
    for rejoin_s in (3.0, 0.0):
        detector = _ScriptedDetector(people)
        detector.unseen = {(t, 0) for t in hidden}
        live = LivePeople(CAMERA, detector, lifter, FPS, deadline_frames=None, rejoin_s=rejoin_s)
        monitor = SiteMonitor(Site((ROOM,), (DOOR,)), FPS)
        events, let_go = [], []
        for index, image in enumerate(_frames(len(people), people=people)):
            now, finished = live.update(LiveFrame(index, image, time.monotonic()))
            events += monitor.update(index, {p.track: p.joints for p in now})
            let_go += [(index, track) for track in finished]
            for track in finished:
                events += monitor.ended(track.id)
        live.close()
        started = [e["track"] for e in events if e["event"] == "track started"]
        if rejoin_s:
            assert len(started) == 2 and not let_go and not [e for e in events if e["event"] == "track ended"]
            (first,) = [t for t in live.in_view() if 15 not in t.frames]
            assert first.frames == [t for t in range(50) if t not in hidden]
            (rejoin,) = first.rejoins
            assert rejoin.identity == first.id and rejoin.gap_s == pytest.approx(1.1)
        else:
            assert len(started) == 3
            ((at, first),) = let_go
            assert first.frames[-1] == 14 and at < 25


def test_a_camera_too_slow_for_every_frame_takes_them_evenly_and_follows_everybody_in_one_track(tmp_path):
    from ray3d.lifting.lifter import Lifter
    from ray3d.live.people import LivePeople

    class _Slow(_ScriptedDetector):
        def __call__(self, frame, time_left_s=None):
            time.sleep(0.25)  # 2.5 frame intervals a frame, and the rest: a busy machine
            return super().__call__(frame, time_left_s)

    people = _scene(50)
    detector = _Slow(people)
    lifter = Lifter.load()
    lifter.prepare_small_batches()
    source = FrameSource(_frames(len(people), people=people), FPS, "test", paced=True)
    live = LivePeople(CAMERA, detector, lifter, FPS, deadline_frames=source.deadline_frames)
    ended, dropped_once_paced = [], None
    while (frame := source.next()) is not None:
        ended += live.update(frame)[1]
        source.stride = live.stride
        if live.stride >= 3 and dropped_once_paced is None:
            dropped_once_paced = source.dropped
    live.close()
    apart = np.diff(detector.calls[-6:])
    assert live.stride >= 3 and apart.min() >= 3 and np.ptp(apart) <= 1  # every third frame or so, evenly
    # Once the pace was found frames are skipped, not lost (one may be, as the pace changes).
    assert source.dropped - dropped_once_paced <= 1 and source.skipped > 20
    assert source.read == len(detector.calls) + source.dropped + source.skipped == len(people)
    tracks = live.in_view() + ended
    assert len(tracks) == 2 and all(len(t.frames) >= len(detector.calls) - 2 for t in tracks)  # one track each


def test_a_live_run_writes_every_event_and_its_world_file_holds_the_offline_answer(tmp_path):
    from ray3d.lifting.lifter import Lifter
    from ray3d.lifting.options import LiftOptions

    people = _scene()
    summary, detector = _run(tmp_path, people, Site((ROOM,), (DOOR,)), every_s=1.0)
    assert summary.ending == "ended" and summary.processed + summary.dropped == summary.read == len(people)
    lines = (tmp_path / "live" / "events.jsonl").read_text().splitlines()
    events = [json.loads(line) for line in lines]
    assert len(events) == summary.events
    crossings = sorted(e["direction"] for e in events if e["event"] == "line crossed")
    assert crossings == ["back", "forward"]  # one each way
    assert sum(e["event"] == "track started" for e in events) == sum(e["event"] == "track ended" for e in events) == 2
    world = read_world(tmp_path / "live" / "world.csv")
    assert len(world.tracks) == 2 and summary.tracks == 2
    lifter = Lifter.load()
    seen = np.array(detector.calls)  # the frames processed (the others were dropped)
    earlier = []  # what the people who left before said of the camera's ankle plane (the file is in that order)
    for track, result in world.tracks.items():
        person = int(np.argmin(np.linalg.norm(people[result.frames[0], :, 0] - result.joints[0, 0], axis=-1)))
        offline = lifter.lift_tracks({0: (seen, detector.pixels[seen, person])}, CAMERA, "h36m17", world.fps,
                                     **LiftOptions(seen_before=tuple(earlier)).lift_arguments())
        expected = offline[0]  # at the stream's rate (played fast)
        earlier += [e for e in offline.evidence.values() if e is not None]
        np.testing.assert_allclose(result.joints, expected.joints, atol=2e-5)  # CSV keeps 5 decimals
        assert result.refinement["ankle_plane"]["people"] == len(earlier)
        assert result.refinement["stature_m"] == pytest.approx(expected.refinement["stature_m"])
    assert (tmp_path / "live" / "site" / "report.html").exists()
    import csv

    with (tmp_path / "live" / "site" / "by-time.csv").open() as handle:  # the report's buckets, from the world file
        buckets = list(csv.DictReader(handle))
    assert sum(int(b["door: forward"]) + int(b["door: back"]) for b in buckets) >= 1


def test_several_cameras_follow_each_person_once_and_fuse_their_world_files(tmp_path):
    """Two cameras facing each other see the same two people: the events and the page are of two people (each
    crossing counted once), each camera writes its own world file, and the fused world has two tracks, each
    seen by both cameras, near the truth."""
    from ray3d.jobs.live import live_job
    from ray3d.live.runner import LiveOptions

    people = _scene()
    # Every frame processed (as from files read as fast as they are processed): what is tested is who is who
    # across the cameras, not keeping up, which a loaded machine may not (then a person's frames are dropped).
    job, inputs, _ = _two_cameras_facing(people)
    summary = live_job(job, tmp_path / "live", LiveOptions(page=False), lambda job, recorder: inputs,
                       site=Site((ROOM,), (DOOR,))).summary
    assert summary.ending == "ended" and summary.processed == summary.read == 2 * len(people)
    events = [json.loads(line) for line in (tmp_path / "live" / "events.jsonl").read_text().splitlines()]
    started = {e["track"] for e in events if e["event"] == "track started"}
    assert len(started) == 2
    crossings = [e for e in events if e["event"] == "line crossed"]
    assert sorted(e["direction"] for e in crossings) == ["back", "forward"]
    per_camera = sorted((tmp_path / "live").glob("camera*/world.csv"))
    assert len(per_camera) == 2 and all(len(read_world(path).tracks) >= 2 for path in per_camera)
    fused = read_world(summary.files["world"])
    assert summary.files["world"].name == "world.json" and len(fused.cameras) == 2 and len(fused.tracks) == 2
    for track in fused.tracks.values():
        assert track.seen_by.all(axis=1).mean() > 0.8
        truth = people[track.frames, int(np.argmin([np.linalg.norm(people[track.frames[0], p, 0] - track.root[0])
                                                    for p in range(2)]))]
        assert np.median(np.linalg.norm(track.root[:, :2] - truth[:, 0, :2], axis=-1)) < 0.15


def test_live_fusion_joins_a_hand_over_and_never_makes_one_person_of_two_a_camera_sees_at_once():
    from ray3d.fusion.live import LiveFusion
    from ray3d.geometry.uncertainty import PersonNow

    facing = cameras.h36m("S9", "55011271")
    fusion = LiveFusion([CAMERA, facing], frame_period_s=0.1)
    pose = demo_clip()[0] - demo_clip()[0, :1] * [1, 1, 0]

    def at(track: int, x: float, y: float) -> PersonNow:
        return PersonNow(track, pose + [x, y, 0.0], np.array([0.1, 0.03]), 1.7)

    seen = {}
    for k in range(30):  # 3 s: two people 0.6 m apart walking side by side, both cameras see both
        t, x = k / 10, -1.5 + 0.1 * k
        for view in (0, 1):
            for now in fusion.update(view, t, [at(1, x, 0.0), at(2, x, 0.6)]):
                seen.setdefault(now.track, []).append(now.joints[0, 1])
    assert len(seen) == 2 and all(np.ptp(ys) < 0.1 for ys in seen.values())  # never merged, never swapped
    walker = next(n for n, ys in seen.items() if np.median(ys) > 0.3)
    for k in range(30, 40):  # camera 0 keeps the first; the second leaves its view
        fusion.update(0, k / 10, [at(1, -1.5 + 0.1 * k, 0.0)])
    fusion.finished(0, 2)
    fusion.finished(1, 1)
    fusion.finished(1, 2)
    after = []
    for k in range(45, 55):  # 1.1 s after it was last seen, camera 1 sees somebody where the walk led
        after += [now.track for now in fusion.update(1, k / 10, [at(7, -1.5 + 0.1 * k, 0.6)])]
    assert set(after) == {walker}
    fusion.finished(1, 7)
    fusion.finished(0, 1)
    assert sorted(fusion.ended(100.0)) == sorted(seen)
    later = []
    for k in range(1000, 1005):  # somebody new, long after: a new id, never one of those gone
        later += [now.track for now in fusion.update(0, k / 10, [at(9, 0.0, 0.0)])]
    assert set(later) == {str(max(map(int, seen)) + 1)}


def _two_cameras_facing(people: np.ndarray):
    """A live job of two cameras facing each other over ``people`` (every frame waited for), its inputs and its
    frame sources."""
    from ray3d.jobs import CameraChoice, Job
    from ray3d.jobs.live import local_inputs

    facing = cameras.h36m("S9", "55011271")
    sources = [FrameSource(_frames(len(people), people=people, camera=c), FPS, f"scene from {c.name}", waits=True)
               for c in (CAMERA, facing)]
    job = Job(tuple(s.name for s in sources), (CameraChoice(made=CAMERA), CameraChoice(made=facing)),
              video=VideoOptions(min_track_s=0.5))
    return job, local_inputs(job, SourceGroup(sources), [CAMERA, facing],
                             [_ScriptedDetector(people, c) for c in (CAMERA, facing)]), sources


@pytest.mark.parametrize("late_by", [0, 1, 2])
def test_several_cameras_settle_each_frame_once_in_order_whichever_camera_comes_late(tmp_path, late_by):
    """Two cameras' frames of one walk across the door, the second camera's coming ``late_by`` frames after the
    first's: every frame is settled once, in order, from the walk's first frame (what a track saw while who it
    was stayed open counts), the person's settled places go one way only, and the door is crossed once."""

    from ray3d.geometry.uncertainty import PersonNow
    from ray3d.live.cameras import FrameResult
    from ray3d.live.views import Views
    from ray3d.site import SiteMonitor

    facing = cameras.h36m("S9", "55011271")
    fake = types.SimpleNamespace(cameras=[CAMERA, facing], fps=[FPS, FPS], names=["front", "facing"],
                                 sources=["front", "facing"], finish=lambda: [([], []), ([], [])],
                                 set_clocks=lambda offsets_s: None)
    views = Views(fake, tmp_path, None)
    pose = demo_clip()[0] - demo_clip()[0, :1] * [1, 1, 0]
    walk = [SPOT + (0.05 + 0.03 * k) * ACROSS for k in range(30)]  # slowly, over the door

    def frame(view: int, k: int) -> FrameResult:
        place = np.append(walk[k] + 0.02 * (-1) ** view * LOOKING, 0.0)  # the cameras disagree a little
        return FrameResult(k, 0.0, [PersonNow(f"{view}-a", pose + place, np.array([0.1, 0.03]), 1.7)], [], [])

    order = [(0, k) for k in range(late_by)] + [arrival for k in range(30 - late_by)
                                                for arrival in ((0, k + late_by), (1, k))]
    order += [(1, k) for k in range(30 - late_by, 30)]
    settled = []
    for view, k in order:
        settled += views.take(view, frame(view, k))[0]
    settled += views.finish()[0]
    indices = [index for index, _ in settled]
    assert indices == sorted(set(indices)) and indices[0] == 0 and indices[-1] == 29
    assert all(len(people) == 1 for _, people in settled)
    along = [float(np.dot(people[0].joints[0, :2] - SPOT, ACROSS)) for _, people in settled]
    assert np.all(np.diff(along) > 0)
    monitor = SiteMonitor(Site((), (DOOR,)), FPS)
    crossings = [e for index, people in settled for e in monitor.update(index, {p.track: p.joints for p in people})
                 if e["event"] == "line crossed"]
    assert len(crossings) == 1


def test_a_carried_person_goes_on_where_the_cut_off_run_left_them_and_one_not_seen_again_is_ended():
    """Issue 67, item 3: the people a run cut off left in view, taken up by the next run's monitor: no track started
    again, a visit under way goes on (its exit counted, its dwell from its entry), a crossing counted before the
    cut is not counted again on the step from their last known place; one never seen again is ended where the run
    left them (its visit's exit and its track's end, "the service stopped")."""
    from ray3d.site import SiteMonitor
    from ray3d.site.events import CarriedPerson

    def at(point) -> np.ndarray:
        return np.zeros((17, 3)) + [*point, 0.0]

    crossed = CarriedPerson("1-0", tuple(SPOT + 0.2 * ACROSS), 1.0, 2.0, crossed={"door": 1.5})
    visiting = CarriedPerson("1-1", tuple(SPOT + 2.0 * ACROSS), 1.0, 2.0, visits={"room": 0.5})
    gone = CarriedPerson("1-2", tuple(SPOT + 3.0 * ACROSS), 1.8, 2.0, visits={"room": 0.2})
    monitor = SiteMonitor(Site((ROOM,), (DOOR,)), FPS, carried=[crossed, visiting, gone])
    assert monitor.carrying == {"1-0", "1-1", "1-2"} and monitor.occupants["room"] == set()
    events = monitor.update(21, {"1-0": at(SPOT + 0.8 * ACROSS), "1-1": at(SPOT + 2.2 * ACROSS)})
    assert events == [] and monitor.occupants["room"] == {"1-1"} and monitor.carrying == {"1-2"}
    events = monitor.update(22, {"1-0": at(SPOT + 0.2 * ACROSS), "1-1": at(SPOT + 6.0 * ACROSS)})
    assert [(e["event"], e["track"]) for e in events] == [("line crossed", "1-0"), ("zone left", "1-1")]
    assert events[1]["dwell_s"] == pytest.approx(2.2 - 0.5)  # from the visit's entry in the run cut off
    closing = monitor.give_up()
    assert [(e["event"], e["track"], e["time_s"], e["reason"]) for e in closing] == [
        ("zone left", "1-2", 2.0, "the service stopped"), ("track ended", "1-2", 2.0, "the service stopped")]
    assert closing[0]["dwell_s"] == pytest.approx(1.8) and monitor.carrying == set()
    assert monitor.counts["room"] == {"entered": 0, "left": 2} and monitor.counts["door"]["back"] == 1


def test_live_events_follow_the_same_rules_as_the_report_on_the_same_positions():
    from ray3d.site import SiteMonitor

    people = _scene(60)
    fall = people[:, 1].copy()
    fall[30:] = fall[30] * [1, 1, 0] + (fall[30] - fall[30, 0] * [1, 1, 0])[..., [2, 1, 0]] * [1, 1, 0.1]
    fall[30:, :, 2] += 0.05
    tracks = {"0": people[:, 0], "1": fall}
    ruled = Zone("room", ROOM.polygon, max_occupancy=1, max_dwell_s=1.0)
    site = Site((ruled,), (DOOR,))
    world = World({t: LiftResult(j, np.zeros(j.shape[:2], bool), FPS, np.arange(len(j))) for t, j in tracks.items()},
                  CAMERA, "test")
    live = SiteMonitor(site, FPS)
    found = []
    for index in range(len(people)):
        found += live.update(index, {t: j[index] for t, j in tracks.items()})
    for track in tracks:
        found += live.ended(track)
    offline = site_events(world, site)
    key = lambda e: (e["event"], e["track"], round(e["time_s"], 6))  # noqa: E731
    assert sorted(map(key, found)) == sorted(map(key, offline))
    assert any(e["event"] == "fall" for e in found)
    # The causal engine finds what each whole track holds: its crossings, visits and falls.
    from ray3d.site.falls import falls

    times = np.arange(len(people)) / FPS
    for track, joints in tracks.items():
        mine = [e for e in found if e["track"] == track]
        crossed = [(round(c["time_s"], 6), c["direction"]) for c in line_crossings(times, joints[:, 0, :2], DOOR)]
        assert [(round(e["time_s"], 6), e["direction"]) for e in mine if e["event"] == "line crossed"] == crossed
        inside = ruled.contains(joints[:, 0, :2])  # each visit: from the first frame inside to the first outside
        steps = np.diff(inside.astype(int))
        entries, exits = times[1:][steps == 1], times[1:][steps == -1]
        assert [e["time_s"] for e in mine if e["event"] == "zone entered"] == entries.tolist()
        began = np.concatenate([[times[0]] if inside[0] else [], entries])[:len(exits)]
        assert [e["dwell_s"] for e in mine if e["event"] == "zone left"] == np.round(exits - began, 3).tolist()
        assert [e["time_s"] for e in mine if e["event"] == "fall"] == [f["time_s"] for f in falls(times, joints)]


def test_the_page_its_state_and_its_feed_and_a_token_when_asked(tmp_path):
    from starlette.testclient import TestClient

    from ray3d.live.server import LiveBoard, LiveServer, live_app

    board = LiveBoard({"zones": [], "lines": [{"name": "door", "start": [0, -1], "end": [0, 1]}]})
    board.publish({"frame": 3, "people": []})
    client = TestClient(live_app(board))
    assert "<canvas" in client.get("/").text
    assert client.get("/state").json()["frame"] == 3
    assert client.get("/site").json()["lines"][0]["name"] == "door"
    board.close()  # the feed sends the newest snapshot, then ends with the stream
    with client.stream("GET", "/stream") as feed:
        text = "".join(feed.iter_text())
    assert 'data: {"frame": 3' in text and "event: end" in text
    guarded = TestClient(live_app(board, token="s3cret"))
    assert guarded.get("/state").status_code == 401
    assert guarded.get("/state?token=s3cret").status_code == 200
    assert guarded.get("/state", headers={"Authorization": "Bearer s3cret"}).status_code == 200
    with pytest.raises(InputError, match="needs a token"):
        LiveServer(board, host="0.0.0.0")
    server = LiveServer(LiveBoard(), port=0)
    url = server.start()
    assert url.startswith("http://127.0.0.1:")
    import urllib.request
    assert b"<canvas" in urllib.request.urlopen(url, timeout=5).read()
    server.stop()


def test_the_webhook_delivers_every_event_and_a_refusing_one_is_reported_once_without_slowing_anyone():
    from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

    from ray3d.live.outputs import Webhook

    received = []

    class Receiver(BaseHTTPRequestHandler):
        def do_POST(self):
            received.append(json.loads(self.rfile.read(int(self.headers["Content-Length"]))))
            self.send_response(204)
            self.end_headers()

        def log_message(self, *args):
            pass

    server = ThreadingHTTPServer(("127.0.0.1", 0), Receiver)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    hook = Webhook(f"http://127.0.0.1:{server.server_address[1]}/")
    hook.post([{"event": "line crossed", "n": n} for n in range(20)])
    hook.close()
    server.shutdown()
    assert [e["n"] for e in received] == list(range(20)) and hook.delivered == 20
    lines = []
    refused = Webhook(f"http://127.0.0.1:{server.server_address[1]}/", attempts=2, backoff_s=0.01,
                      report=lines.append, queue_size=5)
    start = time.monotonic()
    refused.post([{"event": "x", "n": n} for n in range(8)])
    assert time.monotonic() - start < 0.1  # posting never waits for the receiver
    refused.close(wait_s=1.0)
    assert len(lines) == 1 and "not delivered after 2 attempts" in lines[0]
    assert refused.delivered == 0 and refused.failed + refused.dropped == 8 and refused.dropped >= 3


def test_a_world_file_read_while_it_grows_gives_whole_frames(tmp_path, rng):
    result = LiftResult(rng.normal(size=(5, 17, 3)), np.zeros((5, 17), bool), FPS, np.arange(5),
                        refinement={"stature_m": 1.7})
    path = tmp_path / "world.csv"
    append_world_csv(path, World({"4": result}, CAMERA, "test"))
    append_world_csv(path, World({"9": result}, CAMERA, "test"))
    whole = read_world(path)
    assert list(whole.tracks) == ["4", "9"] and whole.tracks["9"].refinement == {"stature_m": 1.7}
    np.testing.assert_allclose(whole.tracks["9"].joints, result.joints, atol=1e-5)
    text = path.read_text()
    path.write_text(text[:-300])  # a reader catching the last write half done
    cut = read_world(path)
    assert len(cut.tracks["9"].frames) == 4 and np.allclose(cut.tracks["9"].joints, result.joints[:4], atol=1e-5)


SIGNAL_SCRIPT = """
import sys, threading, numpy as np
sys.path.insert(0, {tests!r})
from test_live import _scene, _ScriptedDetector, _frames, CAMERA
from ray3d.jobs import CameraChoice, Job
from ray3d.jobs.live import live_job, local_inputs
from ray3d.lifting.options import VideoOptions
from ray3d.live.runner import LiveOptions
from ray3d.live.source import FrameSource, SourceGroup
people = _scene(400)
source = FrameSource(_frames(400, people=people), 10.0, "scene", paced=True)
job = Job(("scene",), (CameraChoice(made=CAMERA),), video=VideoOptions(min_track_s=0.5))
def opened(job, recorder):
    inputs = local_inputs(job, SourceGroup([source]), [CAMERA], [_ScriptedDetector(people)])
    print("started", flush=True)  # the model loaded; the signals are caught from the next moment on
    return inputs
run = live_job(job, {out!r}, LiveOptions(page=False), opened, signals=True)
print(run.summary.ending, run.summary.processed, flush=True)
sys.exit(128 + run.signal if run.signal else 0)
"""


@pytest.mark.parametrize("number", ["SIGINT", "SIGTERM"])
def test_a_signal_ends_the_stream_with_every_output_complete(tmp_path, number):
    import signal
    import subprocess
    import sys
    from pathlib import Path

    script = tmp_path / "run.py"
    script.write_text(SIGNAL_SCRIPT.format(tests=str(Path(__file__).parent), out=str(tmp_path / "out")))
    process = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)
    assert process.stdout.readline().strip() == "started"
    time.sleep(2.5)
    process.send_signal(getattr(signal, number))
    out, err = process.communicate(timeout=120)
    assert process.returncode == 128 + getattr(signal, number), err
    assert out.split()[0] == "stopped"
    events = [json.loads(line) for line in (tmp_path / "out" / "events.jsonl").read_text().splitlines()]
    assert sum(e["event"] == "track ended" for e in events) == sum(e["event"] == "track started" for e in events) == 2
    world = read_world(tmp_path / "out" / "world.csv")
    assert len(world.tracks) == 2 and all(len(r.frames) > 10 for r in world.tracks.values())


@needs_chromium
def test_the_page_shows_people_moving_and_the_counts_of_the_event_stream_in_headless_chromium(tmp_path):
    import urllib.request

    from ray3d.jobs.live import live_job
    from ray3d.live.runner import LiveOptions

    people = _scene(600)  # a minute: the stream runs until the screenshots are taken, then it is stopped
    job, source, opened = _one_camera(people, FPS)
    listening, stop = threading.Event(), threading.Event()
    urls = []

    def started(url):
        urls.append(url)
        listening.set()

    runner = threading.Thread(target=live_job, args=(job, tmp_path / "live", LiveOptions(port=0, every_s=2.0),
                                                     opened),
                              kwargs={"site": Site((ROOM,), (DOOR,)), "started": started, "stop": stop})
    runner.start()
    assert listening.wait(30)
    for _ in range(100):  # people on the page's feed (the stream has begun)
        if len(json.loads(urllib.request.urlopen(urls[0] + "state", timeout=5).read()).get("people", [])) == 2:
            break
        time.sleep(0.1)

    def drawn(shot: np.ndarray) -> np.ndarray:
        plan = shot[60:540, 8:630]  # the floor plan's canvas: its dots, trails, zones and lines
        return np.abs(plan - plan.mean(axis=-1, keepdims=True)).max(axis=-1) > 60

    shots = []
    for k in range(2):
        time.sleep(1.0)
        for attempt in range(3):  # headless Chromium's --timeout sometimes stops the page before its feed's first
            shot = screenshot(urls[0], tmp_path / f"page{k}-{attempt}.png", size="1100,800", live=True,
                              wait_s=3.0 * (attempt + 1))  # a loaded machine starts Chromium slowly: wait longer
            if drawn(shot).sum() > 200:  # snapshot arrives; another launch is another page
                break
        shots.append(shot)
    state = json.loads(urllib.request.urlopen(urls[0] + "state", timeout=5).read())
    stop.set()
    source.close()
    runner.join(timeout=60)
    plan = [shot[60:540, 8:630] for shot in shots]
    assert all(drawn(shot).sum() > 200 for shot in shots)
    assert (np.abs(plan[0] - plan[1]).max(axis=-1) > 60).sum() > 50  # the people moved between the two
    events = [json.loads(line) for line in (tmp_path / "live" / "events.jsonl").read_text().splitlines()]
    upto = [e for e in events if e["frames"][-1] <= state["frame"] and e["event"] == "line crossed"]
    assert state["counts"]["door"] == {"forward": sum(e["direction"] == "forward" for e in upto),
                                       "back": sum(e["direction"] == "back" for e in upto)}
    assert len(state["people"]) == 2
    # The counts per 2 s bucket add up to the counts so far; the page shows them as a table.
    assert state["buckets"] and state["buckets"][0]["start_s"] == 0.0
    assert sum(b["door: forward"] + b["door: back"] for b in state["buckets"]) == sum(state["counts"]["door"].values())
    assert sum(b["room: entries"] for b in state["buckets"]) == state["counts"]["room"]["entered"]


def test_a_stream_that_stalls_ends_the_run_with_its_outputs_complete(tmp_path):
    from ray3d.jobs.live import live_job
    from ray3d.live.runner import LiveOptions

    people = _scene(60)
    job, _, opened = _one_camera(people, 20.0, "camera 3", stall_timeout_s=0.5, stall_after=40, stall_s=3.0)
    summary = live_job(job, tmp_path / "live", LiveOptions(page=False), opened).summary
    assert summary.ending == "stalled" and summary.why == "camera 3: no frame for 0.5 s: the stream stalled"
    events = [json.loads(line) for line in (tmp_path / "live" / "events.jsonl").read_text().splitlines()]
    assert sum(e["event"] == "track ended" for e in events) == 2
    world = read_world(tmp_path / "live" / "world.csv")
    assert len(world.tracks) == 2 and max(r.frames[-1] for r in world.tracks.values()) == 39


def test_a_webhook_that_hangs_never_holds_up_the_stream_and_closing_it_is_bounded():
    from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

    from ray3d.live.outputs import Webhook

    class Hanging(BaseHTTPRequestHandler):
        def do_POST(self):
            time.sleep(3.0)

        def log_message(self, *args):
            pass

    server = ThreadingHTTPServer(("127.0.0.1", 0), Hanging)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    lines = []
    hook = Webhook(f"http://127.0.0.1:{server.server_address[1]}/", timeout_s=0.3, attempts=1, report=lines.append)
    start = time.monotonic()
    hook.post([{"event": "fall", "n": n} for n in range(5)])
    assert time.monotonic() - start < 0.1
    hook.close(wait_s=0.5)
    assert time.monotonic() - start < 2.5  # the queue's wait plus one attempt's timeout
    assert hook.delivered == 0 and hook.failed + hook.dropped == 5 and len(lines) == 1
    server.shutdown()


def test_live_cameras_whose_files_place_the_floor_differently_are_refused_as_offline(tmp_path):
    """Two cameras of one run whose files place the site's one floor differently (``floor_z_m``): refused before
    a frame is followed, naming the file and the field, as ``ray3d lift`` refuses them (``Job.lift_options``, one
    rule on both clocks; each camera on its own floor regions: tests/test_jobs.py)."""
    from ray3d.jobs import CameraChoice, Job
    from ray3d.jobs.live import local_inputs

    facing = cameras.h36m("S9", "55011271")
    files = []
    for k, (camera, floor_z) in enumerate(((CAMERA, -0.2), (facing, 0.1))):
        path = tmp_path / f"camera{k}.json"
        path.write_text(json.dumps({**camera.to_dict(), "floor_z_m": floor_z}))
        files.append(str(path))
    sources = [FrameSource(iter(()), FPS, f"scene from {c.name}", waits=True) for c in (CAMERA, facing)]
    job = Job(tuple(s.name for s in sources), tuple(CameraChoice(file) for file in files))
    try:
        with pytest.raises(InputError, match=r"camera1.json: floor_z_m 0.1 where .*camera0.json says -0.2: the "
                                             "cameras of one site stand on one floor"):
            local_inputs(job, SourceGroup(sources), [CAMERA, facing], [_ScriptedDetector(_scene(4), c)
                                                                         for c in (CAMERA, facing)])
    finally:
        for source in sources:
            source.close()


def _lifted_people(finished: list) -> list[int]:
    """How many people each lifted track's floor was found from (``ankle_plane.people``), in the order lifted."""
    return [next(iter(f.world.tracks.values())).refinement["ankle_plane"]["people"] for f in finished]


def test_the_cameras_of_a_live_run_lift_on_one_floor_from_all_their_people(tmp_path):
    """Two cameras of one run (one world frame, one floor) pool what their people show of it
    (``live.floor.FloorPool``): the second camera's lifts count the first camera's people too."""
    people = _scene(20)
    _, inputs, sources = _two_cameras_facing(people)
    followed = inputs.followed
    lifted = []
    for view, source in zip(followed.views, sources):  # the first camera's people all lifted before the second's
        done = [f for frame in iter(source.next, None) for f in view.process(frame).done]
        lifted.append(done + view.finish()[1])
    first, second = len(lifted[0]), len(lifted[1])
    assert first >= 2 and second >= 2
    assert _lifted_people(lifted[0]) == list(range(1, first + 1))
    assert _lifted_people(lifted[1]) == list(range(first + 1, first + second + 1))  # on their own: 1, 2, ...
    assert len(followed.floor.evidence()) == first + second
    # Each lifted track brings its rays of the pelvis and ankles, to be crossed where the join finds two one.
    floor = lifted[1][0].floor
    assert floor.rays.shape == (len(floor.frames), 3, 3) and floor.seen.all() and len(floor.evidence) == 1


def test_the_page_state_carries_each_cameras_floor_as_its_latest_lift_decided_it(tmp_path, monkeypatch):
    """Once a person's track is lifted, the page's state (``/state``) says where its camera's people put the floor
    and what was done with it, in one line (``AnklePlane.message``) and in numbers; the page draws the line."""
    from importlib import resources

    from ray3d.live.server import LiveBoard

    published = []
    publish = LiveBoard.publish
    monkeypatch.setattr(LiveBoard, "publish", lambda board, snapshot: (published.append(snapshot),
                                                                      publish(board, snapshot)))
    people = _scene(50)
    detector = _ScriptedDetector(people)
    detector.unseen = {(frame, 1) for frame in range(10, 50)}  # the second person leaves early: lifted meanwhile
    _run(tmp_path, people, fps=FPS, detector=detector)
    assert published[0]["floor"] == []  # nobody lifted yet
    floor = published[-1]["floor"]
    assert [line["camera"] for line in floor] == [CAMERA.name] and floor[0]["people"] == 1
    from ray3d.refine.ankle_plane import AnklePlane

    lifted_first = next(iter(read_world(tmp_path / "live" / "world.csv").tracks.values()))  # the one who left
    plane = AnklePlane.from_summary(lifted_first.refinement["ankle_plane"])
    assert floor[0]["line"] == plane.message(CAMERA.name) and CAMERA.name in floor[0]["line"]
    assert floor[0]["decision"] == plane.decision and floor[0]["chance_off"] == pytest.approx(plane.chance_off,
                                                                                               abs=1e-3)
    assert floor[0]["observed_sd_m"] > 0 and abs(floor[0]["observed_m"]) < 0.5
    page = resources.files("ray3d").joinpath("assets", "live.html").read_text()
    assert 'id="floor"' in page and "state.floor" in page


def test_two_cameras_tracks_joined_as_one_person_are_crossed_once_both_are_lifted_whichever_comes_first():
    """``live.floor.JoinedAnkles``: a person two cameras saw at once, their ankle keypoints 0.1 m up (the detector's
    planted ankle), is the floor itself at 0 once both tracks are lifted, the join decided before or after."""
    from ray3d.live.floor import JoinedAnkles, TrackFloor

    frames = np.arange(20)  # 2 s at 10 frames/s
    standing = np.array([[0.0, 0.0, 0.95], [0.1, 0.0, 0.1], [-0.1, 0.0, 0.1]])  # pelvis, ankles

    def lifted(centre) -> TrackFloor:
        rays = np.repeat((standing - centre)[None], len(frames), axis=0).astype(np.float32)
        return TrackFloor((), "h36m17", 0.1, np.array(centre), frames, rays, np.ones((len(frames), 3), bool), FPS)

    first, second = lifted([4.0, 0.0, 2.5]), lifted([0.0, 4.0, 2.5])
    joins = JoinedAnkles(lambda view, frames: frames)
    assert joins.joined([(0, "a"), (1, "b")]) == [] and joins.lifted(0, "a", first) == []
    [(crossing, pair)] = joins.lifted(1, "b", second)
    assert pair == (0, 1) and crossing.height_m == pytest.approx(0.0, abs=1e-5) and crossing.seconds == 2.0
    assert joins.lifted(0, "c", first) == [] and joins.lifted(1, "d", second) == []
    assert [pair for _, pair in joins.joined([(0, "c"), (1, "d")])] == [(0, 1)]
    assert joins.lifted(0, "e", first) == [] and joins.joined([(0, "e")]) == []  # one camera's alone: nothing
    assert joins.lifted(1, "f", None) == [] and joins.joined([(0, "g"), (1, "f")]) == []
    assert joins.lifted(0, "g", first) == []  # its other camera's track gave no rays (too short, say)


def test_falling_behind_is_a_stretch_with_more_than_its_share_of_a_window_dropped_said_as_it_begins_and_ends():
    from ray3d.live.health import Keeping

    said, recorded = [], []
    keeping = Keeping(["door"], [10.0], window_s=10.0, share=0.02, report=said.append, recorded=recorded.append)
    read = dropped = 0
    for frame in range(600):  # a minute at 10 frames/s; from 20 s to 30 s one frame in four is dropped
        read += 1
        if 200 <= frame < 300 and frame % 4 == 0:
            dropped += 1
            continue
        keeping.observe(0, frame / 10, read, dropped)
    keeping.finish()
    assert said[0] == ("camera door: falling behind: 3 % of frames dropped and 0.00 people a frame left for the next "
                       "over the last 10 s; counts from now on are uncertain")
    assert said[1].startswith("camera door: keeping up again after ") and len(said) == 2
    assert len(recorded) == 1 and keeping.stretches == recorded
    stretch = recorded[0]
    assert stretch.from_s == pytest.approx(19.9) and stretch.to_s == pytest.approx(29.7)  # its first to last drop
    assert 0.2 < stretch.share < 0.3 + 1e-9
    state = keeping.state()
    assert not state["falling_behind"] and state["stretches"][0]["dropped_percent"] == round(100 * stretch.share, 1)
    quiet = Keeping(["door"], [10.0], report=said.append)
    for frame in range(600):  # one frame dropped at the start, one later: under 2 % of any 10 s
        quiet.observe(0, frame / 10, frame + 1, int(frame >= 1) + int(frame >= 300))
    quiet.finish()
    assert quiet.stretches == [] and len(said) == 2
    # Over a one-second window one frame dropped is 10 %, but a single frame is a hiccup; two in a second are not.
    hiccup = Keeping(["door"], [10.0], window_s=1.0, report=lambda line: None)
    for frame in range(100):
        hiccup.observe(0, frame / 10, frame + 1, int(frame >= 30) + int(frame >= 60) + int(frame >= 61))
    hiccup.finish()
    assert len(hiccup.stretches) == 1 and hiccup.stretches[0].from_s == pytest.approx(5.9)
    # No frame dropped, but the detector leaving people for the next frame (to keep its deadline) from 20 s on: a
    # stretch too, its people counted.
    postponing = Keeping(["door"], [10.0], report=said.append)
    for frame in range(600):
        postponing.observe(0, frame / 10, frame + 1, 0, max(0, frame - 200))
    postponing.finish()
    assert len(postponing.stretches) == 1 and postponing.stretches[0].from_s == pytest.approx(20.0)
    assert postponing.stretches[0].dropped == 0 and postponing.stretches[0].postponed > 300
    assert "people a frame left for the next" in said[2] and "people left for the next frame" in said[3]
    # Frames taken evenly, every k-th, are not lost: said as the pace changes, shown in the state, no stretch.
    paced, lines = Keeping(["door"], [10.0], report=said.append), len(said)
    for frame in range(0, 300, 1):
        stride = 2 if 100 <= frame < 200 else 1
        if frame % stride == 0:
            paced.observe(0, frame / 10, frame + 1, 0, 0, stride=stride)
        if frame == 150:
            assert paced.state()["frames_apart"] == {"door": 2}
    paced.finish()
    assert paced.stretches == [] and paced.state()["frames_apart"] == {"door": 1}
    assert said[lines:] == ["camera door: the machine cannot follow every frame: 1 frame in 2 taken from 10.0 s "
                            "(5.0 frames/s), everybody still followed",
                            "camera door: every frame taken again from 20.0 s"]
