"""2D pose detectors: anything with a ``layout`` (a ``ray3d.skeleton`` layout name) that maps an RGB frame to
the people in it, each a ``Detection``. Both detectors run offline from registry packages
(``pip install 'ray3d[video]'``): their weights ship inside the mediapipe wheel.

- ``combined`` (default): every person in view of a fixed camera, moving or still, near or far, from any side.
  The regions of the people found in the previous frame, the people a full-frame person finder finds (``finder``:
  MoveNet MultiPose, which needs no face, ``movenet``: people who stand still, walk away, fill the frame), and
  moving foreground cut into person-sized regions (``proposals``: small, far people the finder misses);
  BlazePose's landmark network on an upscaled crop of each (``landmarks``), duplicates removed.
- ``people``: the same without the full-frame detector (motion and the previous frame only): the finder of
  earlier versions, a little faster where every person is small and walks.
- ``mediapipe``: MediaPipe Pose's own graph, one person per frame, for a close-up of one person (it jumps
  between people in a crowd).
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import time
from collections import deque
from typing import Protocol

import numpy as np

from ray3d.console import native_chatter_dropped
from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.skeleton import BLAZEPOSE33
from ray3d.video.boxes import box_overlap, matched_one_to_one, whole_person
from ray3d.video.landmarks import BlazePoseLandmarks, as_regions
from ray3d.video.movenet import MoveNetPeople, as_blazepose, person_regions
from ray3d.video.proposals import ROI_MARGIN, ForegroundProposals, median_background

# With a full-frame finder, motion where crops found nobody in each of the last EMPTY_RUN frames (a car, a flag, a
# shadow) is looked at only every EMPTY_EVERY-th frame while it goes on: a person who steps out of it is looked at
# within that many frames (the finder looks in between), and followed from then on.
EMPTY_RUN = 8
EMPTY_EVERY = 4
# A person the finder found counts as posed by the landmark network where a pose's whole-person box overlaps theirs
# this much; one not posed needs this many of the finder's own keypoints seen to stand in.
UNPOSED_OVERLAP = 0.4
MIN_UNPOSED_JOINTS = 8


@dataclasses.dataclass(frozen=True)
class Detection:
    """One person in one frame: pixels (J, 2) and confidences (J,) in the detector's layout, how sure the
    detector is that it is a person (0-1), and, from detectors that track, the region (centre u, centre v, side,
    rotation) to look for them in the next frame."""

    pixels: np.ndarray
    confidences: np.ndarray
    score: float
    following: np.ndarray | None = None

    @functools.cached_property
    def box(self) -> np.ndarray:
        """(4,) x0, y0, x1, y1 around the joints seen with confidence 0.5 or more (all if fewer than two are)."""
        seen = self.pixels[self.confidences >= 0.5]
        seen = seen if len(seen) >= 2 else self.pixels
        return np.concatenate([seen.min(axis=0), seen.max(axis=0)])


class PoseDetector(Protocol):
    """``detector(frame)`` with an (H, W, 3) uint8 RGB frame returns the people in it; ``time_left_s``, where
    given, is the time the call may take (live use: a detector that can may leave some people for the next
    frame); ``prepare(frames)`` is given frames spread over the whole video before the first call (a fixed
    camera's empty scene); ``name`` says which detector it is."""

    layout: str
    name: str

    def prepare(self, frames: list[np.ndarray]) -> None: ...

    def __call__(self, frame: np.ndarray, time_left_s: float | None = None) -> list[Detection]: ...


class PeopleDetector:
    """Every person in view of a fixed camera (see the module's note).

    Args:
        camera: the video's camera; its geometry says how tall a person looks at each floor pixel.
        min_score: the landmark network's person score below which a crop holds nobody.
        threads: CPU threads for the networks.
        finder: the full-frame person finder (``MoveNetPeople``): looked in where it finds somebody
            (``combined``), its own keypoints standing in for a person whose crop gave the landmark network nobody;
            None: motion and the previous frame only (``people``).
        full_frame_every: run the finder on every n-th frame only (the people it found are followed from frame
            to frame anyway; somebody new who stands still is found up to n - 1 frames later).
        empty_every: look at motion that crops found nobody in for ``EMPTY_RUN`` frames running on every n-th
            frame only while it lasts (1: every frame; ``combined_detector`` offline: ``EMPTY_EVERY``, its finder
            looking in between).

    Called with ``time_left_s`` (live use), the crops that would not fit in that time are left out: first
    motion's proposals where crops lately found nobody, then people followed from the last frame, who are
    looked at first in the next (everybody at least every other frame; the nearest, the largest, who move
    most in the picture, kept first); new people always. Without it every crop is looked at in every frame, but
    motion that crops found nobody in for ``EMPTY_RUN`` frames running (a passing car) is looked at every
    ``empty_every``-th frame while it lasts.
    """

    layout = BLAZEPOSE33.name

    def __init__(self, camera: Camera, min_score: float = 0.5, threads: int = 2,
                 finder: MoveNetPeople | None = None,
                 full_frame_every: int = 1, empty_every: int = 1):
        self.camera, self.min_score, self.full_frame_every = camera, min_score, max(1, int(full_frame_every))
        self.empty_every, self._frames_seen = max(1, int(empty_every)), 0
        self.name = "combined" if finder is not None else "people"
        self._landmarks, self._finder = BlazePoseLandmarks(threads), finder
        self._proposals = ForegroundProposals(camera)
        self._previous: list[Detection] = []
        self._left_out: list[Detection] = []    # people of an earlier frame not looked at in the last one
        self.crop_s = 0.015                     # the landmark network's time per crop, as measured
        self._empty = _EmptyMotion()
        self.postponed = 0                      # people left for the next frame so far (with ``time_left_s``)

    def prepare(self, frames: list[np.ndarray]) -> None:
        self._proposals = ForegroundProposals(self.camera, median_background(frames) if frames else None)
        self._previous, self._left_out = [], []
        self._empty = _EmptyMotion()

    def __call__(self, frame: np.ndarray, time_left_s: float | None = None) -> list[Detection]:
        # The people of the last frame are looked for where they were (also when they stopped, or merged with
        # others into one blob), and the people the full-frame detector finds where they are not among them; a
        # moving blob is looked at only where it is none of these; then, once more, where part of a blob is left
        # that nobody found explains (the second of two walking together).
        started = time.perf_counter()
        followed = self._previous + self._left_out
        known = as_regions([self._region_around(d) for d in followed])
        looks_whole = self._finder is not None and self._frames_seen % self.full_frame_every == 0
        self._frames_seen += 1
        seen_whole = self._finder.found(frame) if looks_whole else (np.zeros((0, 4)), np.zeros((0, 17, 3)),
                                                                          np.zeros(0))
        whole = person_regions(*seen_whole[:2])
        new = whole[~_near(whole, known)]
        blobs = self._proposals.blobs(frame)
        proposed = as_regions(self._proposals.split_blobs(blobs))
        boxes = np.array([d.box for d in followed]).reshape(-1, 4)
        fresh = proposed[~_near(proposed, known) & ~_inside(proposed[:, :2], boxes) & ~_near(proposed, new)
                         & ~_inside_regions(proposed, new)]
        stale = self._empty.still(fresh) if self._frames_seen % self.empty_every else np.zeros(len(fresh), bool)
        self._empty.now = [fresh[stale]]  # not looked at: presumed empty still, until the next look tells
        fresh = fresh[~stale]
        # A region the full-frame detector found one person in may hold a person wider than motion's
        # proposals allow (arms and legs spread).
        vouched = np.concatenate([_near(known, whole), np.ones(len(new), bool), np.zeros(len(fresh), bool)])
        regions = np.concatenate([known, new, fresh])
        looked = np.ones(len(regions), bool)
        if time_left_s is not None:
            looked[self._left_for_later(regions, len(known), len(new), fresh,
                                        time_left_s - (time.perf_counter() - started))] = False
        found = self._look(frame, regions[looked], vouched[looked])
        if self._finder is not None and not looks_whole and time_left_s is None and len(known):
            # Somebody followed was not found again where they were (close up, swaying, turning): offline, where
            # no deadline is kept, the finder looks now rather than at its turn.
            found_at = as_regions([self._region_around(d) for d in found])
            if (looked[:len(known)] & ~_near(known, found_at)).any():
                seen_whole = self._finder.found(frame)
                whole = person_regions(*seen_whole[:2])
                again = whole[~_near(whole, found_at)]
                found += self._look(frame, again, np.ones(len(again), bool))
        left_out = [d for d, look in zip(followed, looked) if not look]
        self.postponed += len(left_out)
        if found:
            explained = np.stack([d.box for d in found + left_out])
            found += self._look(frame, self._proposals.unexplained(blobs, explained))
        found += self._unposed(*seen_whole, found + left_out)
        self._previous = _without_duplicates(found)
        self._left_out = [d for d in left_out if not len(self._previous) or
                          box_overlap(d.box[None], np.stack([k.box for k in self._previous])).max() < 0.5]
        self._empty.close_frame()
        return self._previous

    def _left_for_later(self, regions: np.ndarray, known: int, new: int, fresh: np.ndarray,
                        seconds: float) -> np.ndarray:
        """The indices of ``regions`` (N, 4: the ``known`` people's, the ``new`` ones', then the ``fresh``
        proposals) not to look at, for the crops to fit in ``seconds`` at their measured time. Looked at always:
        the people left out last time, the new ones, and proposals away from where crops lately found nobody;
        the others as time allows: the last frame's people, largest first, then the proposals where crops
        lately found nobody."""
        previous = np.arange(len(self._previous))
        doubtful = known + new + np.flatnonzero(_near(fresh, self._empty.recent()))
        optional = np.concatenate([previous[np.argsort(-regions[previous, 2], kind="stable")], doubtful])
        room = max(0, int(seconds / self.crop_s) - (len(regions) - len(optional)))
        return optional[room:]

    def _look(self, frame: np.ndarray, regions: np.ndarray, vouched: np.ndarray | None = None) -> list[Detection]:
        """The people the landmark network finds in ``regions`` (N, 4) of the frame; ``vouched`` (N,): the
        regions the full-frame detector found one person in."""
        started = time.perf_counter()
        pixels, confidences, scores, following = self._landmarks(frame, regions)
        if len(regions):  # the time per crop, followed slowly: one busy moment (a new batch size) does not decide it
            per_crop = min((time.perf_counter() - started) / len(regions), 2 * self.crop_s)
            self.crop_s += 0.1 * (per_crop - self.crop_s)
        self._empty.now.append(as_regions(regions)[scores < self.min_score])
        vouched = np.zeros(len(regions), bool) if vouched is None else vouched
        found = [(Detection(p, c, float(s), f if self._finder is not None else None), v)
                 for p, c, s, f, v in zip(pixels, confidences, scores, following, vouched) if s >= self.min_score]
        return [d for d, v in found if _person_sized(self._proposals, d, v)]

    def _unposed(self, boxes: np.ndarray, keypoints: np.ndarray, scores: np.ndarray,
                 posed: list[Detection]) -> list[Detection]:
        """The people the finder found whose crops gave the landmark network nobody there (partly hidden, in a
        crowd, small), each with the finder's own keypoints (``movenet.as_blazepose``) and its region for the next
        frame's crop."""
        if not len(boxes):
            return []
        if posed:
            covered = posed_by(boxes, np.stack([d.box for d in posed]))
            boxes, keypoints, scores = boxes[~covered], keypoints[~covered], scores[~covered]
        pixels, confidences = as_blazepose(keypoints)
        regions = person_regions(boxes, keypoints)
        found = [Detection(p, c, float(s), r) for p, c, s, r in zip(pixels, confidences, scores, regions)]
        return [d for d in found
                if (d.confidences >= 0.5).sum() >= MIN_UNPOSED_JOINTS and _person_sized(self._proposals, d, True)]

    def _region_around(self, detection: Detection) -> np.ndarray:
        """(4,) the crop region (centre u, centre v, side, rotation) for looking again at a person found in the last
        frame: around their joints, and where only the upper body was seen (legs hidden, a half-body pose), as
        tall as a person standing there, so the next crop holds all of them."""
        if detection.following is not None:
            return detection.following
        x0, y0, x1, y1 = detection.box
        tall = max(y1 - y0, 0.8 * float(np.nan_to_num(self._proposals.person_height([(x0 + x1) / 2, y1]))))
        return np.array([(x0 + x1) / 2, y0 + tall / 2, ROI_MARGIN * max(tall, x1 - x0), 0.0])



class _EmptyMotion:
    """Where crops found nobody, frame by frame (``frames``: the regions (N, 4) of each of the last ``EMPTY_RUN``;
    ``now``: this frame's so far): motion proposed there again (a passing car) is looked at less often."""

    def __init__(self):
        self.frames: deque = deque(maxlen=EMPTY_RUN)
        self.now: list[np.ndarray] = []

    def still(self, regions: np.ndarray) -> np.ndarray:
        """(N,) whether each of ``regions`` (N, 4) is near a region crops found nobody in, in each of the last
        ``EMPTY_RUN`` frames."""
        if len(self.frames) < EMPTY_RUN:
            return np.zeros(len(regions), bool)
        return np.logical_and.reduce([_near(regions, empty) for empty in self.frames])

    def close_frame(self) -> None:
        """This frame's regions kept, the oldest let go."""
        self.frames.append(np.concatenate(self.now))

    def recent(self) -> np.ndarray:
        """(N, 4) every region crops found nobody in over the frames kept."""
        return np.concatenate(list(self.frames)) if self.frames else np.zeros((0, 4))


def _person_sized(proposals: ForegroundProposals, detection: Detection, vouched: bool = False) -> bool:
    """Whether the detection is between a third and twice a person's height at its feet (``proposals``' camera
    geometry), and not wider than most of it (joints strewn over two people), or, where the full-frame detector
    ``vouched`` for one person, than one and a half times it."""
    x0, y0, x1, y1 = detection.box
    expected = float(proposals.person_height([(x0 + x1) / 2, y1]))
    widest = (1.5 if vouched else 0.75) * expected
    return bool(np.isfinite(expected)) and expected / 3 <= y1 - y0 <= 2 * expected and x1 - x0 <= widest


def _near(regions: np.ndarray, others: np.ndarray) -> np.ndarray:
    """(N,) whether each region (N, 3) frames about the same person as one of ``others`` (M, 3): centres
    within a quarter of the side apart, sides within a factor 1.6 (a neighbour walking close beside counts as
    near: the second look, at the foreground nobody explains, finds them)."""
    if not len(others) or not len(regions):
        return np.zeros(len(regions), dtype=bool)
    gap = np.linalg.norm(regions[:, None, :2] - others[None, :, :2], axis=-1)
    ratio = regions[:, None, 2] / others[None, :, 2]
    return ((gap < regions[:, None, 2] / 4) & (ratio > 1 / 1.6) & (ratio < 1.6)).any(axis=1)


def _inside(points: np.ndarray, boxes: np.ndarray, grow: float = 1.25) -> np.ndarray:
    """(N,) whether each point (N, 2) lies in one of the boxes (M, 4) grown ``grow`` times about its centre (a
    blob's limb, shadow or fragment beside somebody already found)."""
    if not len(boxes) or not len(points):
        return np.zeros(len(points), dtype=bool)
    centre, half = (boxes[:, :2] + boxes[:, 2:]) / 2, grow * (boxes[:, 2:] - boxes[:, :2]) / 2
    return (np.abs(points[:, None] - centre[None]) <= half[None]).all(axis=-1).any(axis=1)


def _inside_regions(regions: np.ndarray, others: np.ndarray) -> np.ndarray:
    """(N,) whether each region's centre (N, 4) lies in one of the ``others`` (M, 4) regions' middle half (a
    fragment of the motion of somebody already being looked at)."""
    if not len(others) or not len(regions):
        return np.zeros(len(regions), dtype=bool)
    half_sides = others[None, :, 2:3] / 4
    return (np.abs(regions[:, None, :2] - others[None, :, :2]) <= half_sides).all(axis=-1).any(axis=1)


def posed_by(finder_boxes: np.ndarray, pose_boxes: np.ndarray) -> np.ndarray:
    """(N,) whether each of the finder's people (N, 4 boxes) is one the landmark network posed (M, 4: the poses'
    joint boxes): one pose for one person, each pose given to the finder's box it overlaps most as a whole person
    (at ``UNPOSED_OVERLAP`` at least). Of two people where one pose was found (the one behind partly hidden,
    both crops framing the one in front), the one it fits less is not posed: the finder's keypoints stand in."""
    return matched_one_to_one(box_overlap(finder_boxes, whole_person(pose_boxes)), UNPOSED_OVERLAP)


def _without_duplicates(detections: list[Detection], overlap: float = 0.5) -> list[Detection]:
    """Greedy non-maximum suppression on the joints' boxes: of two crops that found the same person, the surer."""
    order = sorted(detections, key=lambda d: -d.score * float(d.confidences.mean()))
    kept: list[Detection] = []
    for detection in order:
        if not kept or box_overlap(detection.box[None], np.stack([k.box for k in kept])).max() < overlap:
            kept.append(detection)
    return kept


class MediaPipeDetector:
    """MediaPipe Pose (BlazePose, 33 landmarks), one person, tracking across frames (video mode).

    Its landmarks are surface points (e.g. the hip landmarks lie outside the hip joint centres the mocap has):
    ``ray3d.skeleton`` maps them to H36M-17 joints, and the residual offset is a systematic 2D error the
    shipped models were not trained for (see the README's limitations).
    """

    layout = BLAZEPOSE33.name
    name = "mediapipe"

    def __init__(self, camera: Camera | None = None, min_detection_confidence: float = 0.5,
                 min_tracking_confidence: float = 0.5):
        try:
            from mediapipe.python.solutions import pose
        except ImportError:
            raise InputError("the MediaPipe detector needs the video extra: pip install 'ray3d[video]'") from None
        # model_complexity=1 is the landmark model the wheel bundles; the others would be downloaded.
        self._pose = pose.Pose(static_image_mode=False, model_complexity=1, smooth_landmarks=True,
                               min_detection_confidence=min_detection_confidence,
                               min_tracking_confidence=min_tracking_confidence)
        self._started = False  # its graph's interpreters start, and print their INFO lines, on the first frame

    def prepare(self, frames: list[np.ndarray]) -> None:
        """Nothing to learn from the scene."""

    def __call__(self, frame: np.ndarray, time_left_s: float | None = None) -> list[Detection]:
        """One person: the time allowed does not change what is done."""
        height, width = frame.shape[:2]
        with native_chatter_dropped() if not self._started else contextlib.nullcontext():
            result = self._pose.process(np.ascontiguousarray(frame))
        self._started = True
        if result.pose_landmarks is None:
            return []
        landmarks = result.pose_landmarks.landmark
        pixels = np.array([[m.x * width, m.y * height] for m in landmarks])
        return [Detection(pixels, np.array([m.visibility for m in landmarks]), 1.0)]

    def close(self) -> None:
        self._pose.close()


# The full-frame finder every second frame offline (the people it found followed between, and at once where one was
# lost): on vtest.avi's annotated people (ray3d bench people, 2026-12-07) 52 of 60 at 12.5 frames/s,
# against 51 every frame at 9.1; its identities 0.944 IDF1 against 0.832 (ray3d bench identity). Cut into
# two tiles it found 56, but made half-people of a man close up (real-near's cam02) and kept identities worse (0.899).
OFFLINE_FULL_FRAME_EVERY = 2


def combined_detector(camera: Camera, threads: int = 2, full_frame_every: int = OFFLINE_FULL_FRAME_EVERY,
                      empty_every: int = EMPTY_EVERY, **options) -> PeopleDetector:
    """``PeopleDetector`` with MoveNet as its full-frame finder, run every ``full_frame_every``-th frame; motion where
    crops found nobody for a while looked at every ``empty_every``-th frame (the finder looking in between)."""
    return PeopleDetector(camera, threads=threads, finder=MoveNetPeople(threads), full_frame_every=full_frame_every,
                          empty_every=empty_every, **options)


DETECTORS = {"combined": combined_detector, "people": PeopleDetector, "mediapipe": MediaPipeDetector}
DEFAULT_DETECTOR = "combined"
LIVE_FULL_FRAME_EVERY = 3  # live: the full-frame detector every third frame (0.3 s at 10 frames/s)
DETECTOR_HELP = ("combined (default): everybody in view of a fixed camera, moving or still, near or far; people: "
                 "the same from motion and the previous frame only; mediapipe: one person, close up")


def make_detector(name: str, camera: Camera, live: bool = False) -> PoseDetector:
    """The detector ``name`` for ``camera``; ``live``: as ``ray3d live`` runs it (the full-frame detector on
    every ``LIVE_FULL_FRAME_EVERY``-th frame)."""
    if name not in DETECTORS:
        raise InputError(f"unknown detector {name!r}; one of {', '.join(DETECTORS)}", arguments=("detector",))
    if live and name == "combined":  # live ranks doubtful crops last under time pressure instead: a restarted
        # run looking at stale motion less counted 6-8 % more zone entries (history: results-2026-12-07.md)
        return DETECTORS[name](camera, full_frame_every=LIVE_FULL_FRAME_EVERY, empty_every=1)
    return DETECTORS[name](camera)
