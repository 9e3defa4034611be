"""Who is where, frame by frame, causally: the detector and the floor tracker of ``ray3d video``, each person
lifted as their frame arrives (``LiftStream`` without waiting for the future, everybody in one network call), and
a causal form of the track-level refinement: every ``refine_every_s`` the refinement runs on the person's last
``refine_window_s`` and its factor along the rays for the latest frame carries the frames until the next run.
The refinements run one at a time on a thread of their own below the stream's priority, in the time the
detector's network leaves: one inline cost a frame 50 ms.

A person who has left (unseen for longer than the tracker's gap) is handed over as a finished track; its final
answer is the offline one (``Lifter.lift_tracks`` on the whole track, as ``ray3d video`` lifts it)."""

from __future__ import annotations

import dataclasses
import os
import threading
import time
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np

from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.geometry.floor import FLAT_FLOOR, Floor
from ray3d.geometry.uncertainty import PersonNow
from ray3d.lifting.lifter import Lifter
from ray3d.lifting.stream import LiftStream, lift_streams
from ray3d.live.source import LiveFrame
from ray3d.refine import RefineConfig, network_position_sd, refine_track, scale_about
from ray3d.temporal import OneEuro
from ray3d.video.detectors import PoseDetector
from ray3d.video.identities import REJOIN_WITHIN_S
from ray3d.video.track import Track
from ray3d.video.tracking import CONFIRM_FRAMES, FloorTracker

RUNNER_SHARE = 0.1  # of a frame's period, kept for the events, the outputs and the page after the people
# Under load (a busy machine, a crowded moment) a paced stream's frames are taken evenly, every k-th (``Pacing``),
# rather than some dropped where they pile up and people left for later: the tracker, the lifting and the zones
# then follow everybody at a lower rate, at the frames' true times (issue 68: counts 2-4x too low otherwise).
MOST_FRAMES_APART = 4
PACE_FOLLOWING = 0.1   # the share of each taken frame's work in the work followed (about 10 taken frames)
PACE_FALL_BACK = 0.85  # a frame more is taken again once the work fits in this share of the shorter interval
PACE_WARM_UP = 5       # taken frames not counted at the start (the networks' first calls are slow)
# The One-Euro filter's minimum cutoff (Hz) and its growth per m/s on each person's answers: a frame's jitter and
# the refinement's steps along the ray (every refine_every_s) smoothed, as the offline report's whole tracks are
# (Savitzky-Golay), without which a person near a zone's edge enters and leaves it frame by frame.
LIVE_SMOOTHING = (1.0, 0.05)


@dataclasses.dataclass
class _Following:
    stream: LiftStream
    pushed: int = 0                   # the track's detections lifted so far
    added: int | None = None          # the frame of the last detection the stream took
    history: deque = None             # (frame, raw joints (17, 3)) over the refinement's window
    scale: float = 1.0                # the refinement's factor along the rays for the latest frame
    position_sd: np.ndarray | None = None
    stature_m: float | None = None
    next_refinement: int = 0          # the frame from which the refinement runs again
    latest: PersonNow | None = None   # the answer for the track's latest detection
    smoother: OneEuro = None          # the answers, causally smoothed (as the offline report's are, whole)
    answered: int | None = None       # the frame of the latest answer


class Pacing:
    """Every how many frames of a paced stream to take (``stride``) so that each taken frame's work fits in the
    time until the next: ``observe(seconds)`` with each taken frame's work (its processing and the people the
    detector left for later, at its time per crop), followed slowly; the stride grows as soon as the work does not
    fit and falls back once it fits, with a margin, in one frame less."""

    def __init__(self, fps: float, most: int = MOST_FRAMES_APART):
        self.period_s, self.most, self.stride = 1 / fps, int(most), 1
        self.work_s: float | None = None
        self._observed = 0

    def observe(self, seconds: float) -> int:
        self._observed += 1
        if self._observed <= PACE_WARM_UP:
            return self.stride
        self.work_s = seconds if self.work_s is None else self.work_s + PACE_FOLLOWING * (seconds - self.work_s)
        periods = self.work_s / self.period_s
        if periods > self.stride:
            self.stride = min(self.most, int(np.ceil(periods)))
        elif self.stride > 1 and periods < PACE_FALL_BACK * (self.stride - 1):
            self.stride -= 1
        return self.stride


class LivePeople:
    """``update(frame)`` -> the people in it, and the tracks finished since the last call.

    The detector is given the time left until ``deadline_frames`` taken frames after the frame's arrival (the
    source's buffer: finished by then, the frame pushes none out), less what the rest of a frame takes (as
    measured): a detector that can leaves some people for the next frame rather than fall behind (no deadline,
    ``deadline_frames`` None, for a stream that waits for its reader). Where the work outgrows the frame interval,
    ``stride`` asks for every k-th frame only (``Pacing``; the frames' owner tells their source), each person's
    frames lifted at their true times. A person the
    detector did not see in this frame but did in the one processed before is given at their place of the frame before
    (the page and the zones' counts do not flicker); their world track has only the frames they were seen in."""

    def __init__(self, camera: Camera, detector: PoseDetector, lifter: Lifter, fps: float,
                 floor: Floor = FLAT_FLOOR, max_gap_s: float = 0.5, refine_every_s: float = 3.0,
                 refine_window_s: float = 20.0, deadline_frames: float | None = 2.0, id_prefix: str = "",
                 carried=(), rejoin_s: float = REJOIN_WITHIN_S):
        self.deadline_frames = deadline_frames
        self.pacing = None if deadline_frames is None else Pacing(fps)
        self.camera, self.detector, self.lifter, self.fps, self.floor = camera, detector, lifter, fps, floor
        self.tracker = FloorTracker(camera, fps, detector.layout, max_gap_s, CONFIRM_FRAMES, id_prefix=id_prefix,
                                    carried=carried, rejoin_s=rejoin_s)
        self.config = RefineConfig.for_model(lifter.document, detector.layout)
        self.refine_every = max(1, int(round(refine_every_s * fps)))
        self.window = max(2, int(round(refine_window_s * fps)))
        self._following: dict[int, _Following] = {}
        self._refiner = ThreadPoolExecutor(1, "refine", initializer=below_the_stream)
        self._refining: Future | None = None
        self._after_detection_s = 0.0  # the time a frame takes after its detection, as measured
        self._last_frame = -1          # the frame processed before this one (frames may have been dropped)

    def update(self, frame: LiveFrame, detections: list | None = None) -> tuple[list[PersonNow], list[Track]]:
        """The people in ``frame`` (its ``detections`` when the detector already ran on it) and the tracks
        finished since the last call."""
        started, postponed = time.monotonic(), getattr(self.detector, "postponed", 0)
        if detections is None:
            reserve = self._after_detection_s + RUNNER_SHARE / self.fps
            detections = self.detector(frame.image, time_left_s=None if self.pacing is None else
                                       frame.arrived + self.deadline_frames * self.stride / self.fps - reserve
                                       - time.monotonic())
        detected = time.monotonic()
        self.tracker.update(frame.index, detections, frame.image)
        waiting: list[tuple[int, _Following]] = []
        for track in self.tracker.tracks():
            following = self._following.get(track.id) or self._start(track)
            # A track just confirmed brings the detections that confirmed it: all but the latest are lifted one
            # by one (for the refinement's history); the latest of every track goes into one network call.
            for k in range(following.pushed, len(track.frames)):
                detection = track.detections[k]
                apart = 1 if following.added is None else track.frames[k] - following.added
                try:
                    following.stream.add(detection.pixels, detection.confidences, apart)
                    following.added = track.frames[k]
                except InputError:  # a detection the lifter cannot read (its root unseen): skipped
                    continue
                finally:
                    following.pushed = k + 1
                if k < len(track.frames) - 1:
                    following.history.append((track.frames[k], lift_streams([following.stream])[0]))
                elif track.frames[k] == frame.index:
                    waiting.append((track.id, following))
        answers = lift_streams([f.stream for _, f in waiting])
        for (_, following), raw in zip(waiting, answers):
            following.history.append((frame.index, raw))
        # One refinement at a time, the most overdue, once the last has finished.
        if self._refining is not None and self._refining.done():
            self._refining.result()  # its failure is this stream's
            self._refining = None
        due = [f for _, f in waiting if frame.index >= f.next_refinement and len(f.history) >= 2]
        if due and self._refining is None:
            overdue = min(due, key=lambda f: f.next_refinement)
            self._refining = self._refiner.submit(self._refine, overdue, np.stack([raw for _, raw in overdue.history]))
            overdue.next_refinement = frame.index + self.refine_every
            if self.pacing is None:
                # A stream that waits for us (a file read as fast as it is processed) has no deadline to keep:
                # the answer is awaited, so that the same file gives the same people and events every time.
                self._refining.result()
        people, tracks = [], {track.id: track for track in self.tracker.tracks()}
        for (track_id, following), raw in zip(waiting, answers):
            joints = scale_about(raw[None], self.camera.center, np.array([following.scale]))[0]
            step_s = (frame.index - following.answered) / self.fps if following.answered is not None else 0.0
            joints, following.answered = following.smoother(joints, step_s), frame.index
            sd = following.position_sd if following.position_sd is not None else \
                network_position_sd(raw[None], self.camera, self.config)[0]
            track = tracks[track_id]
            following.latest = PersonNow(track_id, joints, sd, following.stature_m,
                                         np.concatenate([track.floor[-1], track.walk]), track.colour)
            people.append(following.latest)
        people += [self._following[t.id].latest for t in self.tracker.tracks()
                   if t.frames[-1] == self._last_frame and self._following[t.id].latest is not None]
        self._last_frame = frame.index
        finished = self.tracker.finished()
        for track in finished:
            self._following.pop(track.id, None)
        self._after_detection_s += 0.1 * (time.monotonic() - detected - self._after_detection_s)
        if self.pacing is not None:
            left = getattr(self.detector, "postponed", 0) - postponed
            self.tracker.frames_apart = self.pacing.observe(time.monotonic() - started + RUNNER_SHARE / self.fps
                                                            + left * getattr(self.detector, "crop_s", 0.0))
        return people, finished

    @property
    def stride(self) -> int:
        """Every how many frames of its stream to take (1: every one)."""
        return 1 if self.pacing is None else self.pacing.stride

    def _start(self, track: Track) -> _Following:
        stream = self.lifter.stream(self.camera, self.detector.layout, fps=self.fps, wait_for_future=False)
        self._following[track.id] = following = _Following(stream, history=deque(maxlen=self.window),
                                                           smoother=OneEuro(*LIVE_SMOOTHING))
        return following

    def _refine(self, following: _Following, joints: np.ndarray) -> None:
        """The refinement on the person's recent frames' raw joints (T, 17, 3); its answer for the latest frame
        carries on."""
        _, refined = refine_track(joints, self.camera, self.fps, config=self.config, floor=self.floor)
        following.scale = float(refined.scale[-1])
        following.position_sd = refined.position_sd_m[-1]
        following.stature_m = float(refined.stature_m) if np.isfinite(refined.stature_m) else None

    def in_view(self) -> list[Track]:
        """The tracks still followed (at the stream's end, to be finished too)."""
        return self.tracker.tracks()

    def close(self) -> None:
        """Waits for the refinement under way."""
        self._refiner.shutdown(wait=True)


def below_the_stream() -> None:
    """The calling thread below the stream's priority: it takes the time the stream leaves (Linux: threads
    have their own; elsewhere nothing changes)."""
    try:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), 19)
    except (AttributeError, OSError):
        pass
