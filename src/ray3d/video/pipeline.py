"""``lift_video``: frames (OpenCV, streamed) -> the people in each frame -> tracks -> world joints of every
track -> the world file, the detections (to re-lift without detecting again), the HTML viewer and an overlay
video (each person's detections and lifted joints projected back through the camera, with their id).

Frames are read one at a time and never kept: memory holds the detections (a few hundred bytes per person
and frame) and the tracker's state, not the video."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from ray3d.console import progress_bar
from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.io.bvh_export import export_paths
from ray3d.io.detections import TrackDetections
from ray3d.io.keypoints import Keypoints, write_keypoints_json
from ray3d.io.world import World, check_world_output, write_world
from ray3d.lifting.lifter import Lifter
from ray3d.lifting.options import LiftOptions, VideoOptions
from ray3d.temporal import check_frame_rate
from ray3d.video.boxes import outside_picture
from ray3d.video.detectors import PoseDetector
from ray3d.video.frames import VideoInfo, camera_for_video, read_frames, read_video_info, spread_frames
from ray3d.video.identities import Rejoin, rejoin_tracks
from ray3d.video.overlay import write_overlay
from ray3d.video.track import Track
from ray3d.video.tracking import CONFIRM_FRAMES, FloorTracker
from ray3d.viz.html_viewer import write_viewer

SHORT_CLIP_SHARE = 0.5   # a track as long as this share of the clip is kept, however short the clip

@dataclasses.dataclass
class TrackedPeople:
    """Everybody detected and followed in a video: {track id: detections at the video's frame index} of the
    tracks kept, in the detector's layout, at ``fps``; the frames read; {track id: why} of those dropped; the
    video and which detector found them; the re-joins made (``video.identities``)."""

    tracks: dict[str, TrackDetections]
    layout: str
    fps: float
    frames_read: int
    dropped: dict[str, str]
    video: Path
    detector: str = ""
    rejoins: list = dataclasses.field(default_factory=list)

    def rejoined(self) -> dict[str, list[dict]]:
        """{track kept: its re-joins} (what the world file records)."""
        found: dict[str, list[dict]] = {}
        for rejoin in self.rejoins:
            if rejoin.identity in self.tracks:
                found.setdefault(rejoin.identity, []).append(rejoin.to_dict())
        return found

    def in_part(self, image_size: tuple[int, int]) -> dict[str, list[int]]:
        """{track kept: the frames in which the picture's edge cut the person} (what the world file records)."""
        cut = {track: detections.frames[outside_picture(detections.pixels, image_size)].tolist()
               for track, detections in self.tracks.items()}
        return {track: frames for track, frames in cut.items() if frames}

    def keypoints(self) -> Keypoints:
        """The kept tracks' detections as one keypoint record (what ``keypoints.json`` holds)."""
        ids = list(self.tracks)
        return Keypoints(np.concatenate([self.tracks[t].pixels for t in ids]),
                         np.concatenate([self.tracks[t].confidences for t in ids]),
                         np.concatenate([self.tracks[t].frames for t in ids]),
                         np.concatenate([np.full(len(self.tracks[t].frames), t) for t in ids]), self.layout, self.fps,
                         f"{self.layout} detections ({self.detector} detector)", self.video)


@dataclasses.dataclass
class VideoResult:
    """The tracked detections (every track, in the detector's layout), the lifted world, the frames read, the
    tracks dropped (too short, or not liftable: {track id: why}), the files written ({"world", "keypoints",
    "viewer", "overlay"}; a BVH world of several tracks is one file each: "world TRACK") and the seconds each
    stage took (people: reading, detecting and tracking; lifting; writing)."""

    keypoints: Keypoints
    world: World
    frames: int
    dropped: dict[int, str]
    files: dict[str, Path]
    seconds: dict[str, float]


def video_info(video: str | Path | VideoInfo) -> VideoInfo:
    """A video's properties: read from its header unless given already (read once per run)."""
    return video if isinstance(video, VideoInfo) else read_video_info(video)


def _span(info: VideoInfo, options: VideoOptions) -> int:
    """How many frames to read from ``options.start``, checked against the video."""
    start, frames = options.start, options.frames
    if info.frames > 0 and start >= info.frames:
        raise InputError(f"{info.path}: start frame {start} is outside its {info.frames} frames", arguments=("start",))
    left = info.frames - start if info.frames > 0 else None
    return min(frames, left) if frames is not None and left is not None else (frames or left or 0)


def track_video(video: str | Path | VideoInfo, camera: Camera, detector: PoseDetector,
                options: VideoOptions = VideoOptions(), progress: bool = True) -> TrackedPeople:
    """Detect and track everybody in the part of ``video`` that ``options`` select; tracks shorter than
    ``options.min_track_s`` (or half the clip, when that is shorter) are dropped."""
    detector_name = getattr(detector, "name", type(detector).__name__)  # a user's own detector may have none
    info = video_info(video)
    fps = _frame_rate(info, options.fps)
    count = _span(info, options)
    detector.prepare(spread_frames(info, options.start, count) if count else [])
    tracker = FloorTracker(camera, fps, detector.layout, options.max_gap_s, CONFIRM_FRAMES)
    read = 0
    for index, frame in progress_bar(read_frames(info.path, options.start, count or None), shown=progress,
                                     total=count or None, desc="people", unit="frame"):
        tracker.update(index, detector(frame), frame)
        read += 1
    if read == 0:
        raise InputError(f"{info.path}: no frames could be read")
    people = follow_people(tracker.tracks(), fps, read, options)
    kept = {track.id: track.as_detections() for track in people.kept}
    if not kept:
        seen_for = {track.id: track.seconds(fps) for track in people.dropped}
        raise InputError(_nobody_followed(info.path, read, fps, people.shortest_s, seen_for,
                                          tracker.frames_with_people, detector_name),
                         arguments=("min_track_s",) if seen_for else ("detector",))
    dropped = {track.id: track.too_short(fps, people.shortest_s) for track in people.dropped}
    return TrackedPeople(kept, detector.layout, fps, read, dropped, info.path, detector_name, people.rejoins)


@dataclasses.dataclass(frozen=True)
class FollowedPeople:
    """A tracker's tracks as the people reported: one track per identity (re-joined), those ``kept`` and those
    ``dropped`` (followed for less than ``shortest_s``), and the re-joins made."""

    kept: list[Track]
    dropped: list[Track]
    rejoins: list[Rejoin]
    shortest_s: float


def follow_people(tracks: list[Track], fps: float, frames_read: int, options: VideoOptions) -> FollowedPeople:
    """``tracks`` (a ``FloorTracker``'s, over ``frames_read`` frames) -> the people ``ray3d video`` reports: re-joined
    over ``options.rejoin_s``, and without those followed for less than ``options.min_track_s`` (a track that short
    is a box on two people or on part of one as often as a person)."""
    # A short clip keeps a person seen for half of it: one seen in every frame of a 1.7 s clip is a track.
    shortest = min(options.min_track_s, SHORT_CLIP_SHARE * frames_read / fps)
    identities, rejoins = rejoin_tracks(tracks, fps, options.rejoin_s)
    kept = [track for track in identities if track.too_short(fps, shortest) is None]
    dropped = [track for track in identities if track.too_short(fps, shortest) is not None]
    return FollowedPeople(kept, dropped, rejoins, shortest)


def _nobody_followed(path: Path, read: int, fps: float, shortest: float, seen_for: dict[int, float],
                     frames_with_people: int, detector_name: str) -> str:
    """The refusal when no track is kept: what was found, and what would keep it."""
    found = f"{path}: nobody was found and followed for {shortest:.2f} s in its {read} frame(s)"
    if seen_for:
        longest = max(seen_for.values())
        return (f"{found}: {len(seen_for)} candidate track(s), the longest seen for {longest:.2f} s; a minimum "
                f"track length of {np.floor(longest * 100) / 100:.2f} s would keep it")
    if frames_with_people:
        return (f"{found}: the {detector_name} detector found people in {frames_with_people} frame(s) but no one "
                f"in {CONFIRM_FRAMES} frames running")
    return f"{found}: the {detector_name} detector found nobody in any frame (try another detector)"


def _frame_rate(info: VideoInfo, fps: float | None) -> float:
    """The frame rate given, checked, or else the video's own."""
    if fps is not None:
        return check_frame_rate(fps, str(info.path))
    if not info.fps > 0:
        raise InputError(f"{info.path}: the video reports no frame rate; give it", arguments=("fps",))
    return float(info.fps)


def _targets(out_dir: Path, world_format: str, overlay: bool, overwrite: bool) -> dict[str, Path]:
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"{out_dir}: exists and is not a folder", arguments=("out",))
    if out_dir.is_dir() and any(out_dir.iterdir()) and not overwrite:
        raise InputError(f"{out_dir}: the output folder exists and is not empty; refusing to write into it",
                         arguments=("overwrite",))
    return {"world": out_dir / f"world{world_format}", "keypoints": out_dir / "keypoints.json",
            "viewer": out_dir / "viewer.html", **({"overlay": out_dir / "overlay.mp4"} if overlay else {})}


def lift_video(video: str | Path | VideoInfo, camera: Camera, out_dir: str | Path, detector: PoseDetector,
               lifter: Lifter, options: LiftOptions = LiftOptions(),
               video_options: VideoOptions = VideoOptions(), world_format: str = ".json", overlay: bool = True,
               overwrite: bool = False, progress: bool = True) -> VideoResult:
    """Detect, track and lift everybody, and write ``out_dir``/{world.json|.csv|.npz, keypoints.json,
    viewer.html, overlay.mp4}.

    ``video``: a path, or its ``VideoInfo`` when the caller has read it. ``camera`` must have the video's image
    size; ``video_options`` select the frames and how people are followed; ``options`` how they are lifted
    (Savitzky-Golay smoothing of the joints by default: it removes a detector's jitter without lag). The world
    file holds the joints in ``options.frame``; the viewer and overlay draw the world.
    """
    return lift_videos([(video, camera, out_dir, detector)], lifter, options, video_options, world_format, overlay,
                       overwrite, progress)[0]


def lift_videos(inputs: list[tuple], lifter: Lifter, options: LiftOptions | list[LiftOptions] = LiftOptions(),
                video_options: VideoOptions = VideoOptions(), world_format: str = ".json", overlay: bool = True,
                overwrite: bool = False, progress: bool = True, one_clock: bool = True) -> list[VideoResult]:
    """Several videos of one site, each (video, camera, out_dir, detector) as ``lift_video`` takes them: everybody
    in each followed, then everybody lifted together on the site's one floor (``Lifter.lift_cameras``: where
    people's ankles meet it observed from every camera's people, and triangulated where two cameras see a person
    at once if the videos' frames are ``one_clock``), then each video's outputs written; ``options``: one for
    every video, or each video's own. The seconds of the lifting are those of all the videos together."""
    each = list(options) if isinstance(options, (list, tuple)) else [options] * len(inputs)
    if len(each) != len(inputs):
        raise InputError(f"options: one LiftOptions, or one per video ({len(inputs)}); got {len(each)}",
                         ("options",))
    started = []
    for video, camera, out_dir, detector in inputs:
        info = video_info(video)
        started.append((info, camera_for_video(camera, info), Path(out_dir), detector))
    targets = [_targets(out_dir, world_format, overlay, overwrite) for _, _, out_dir, _ in started]
    for target, own in zip(targets, each):
        check_world_output(target["world"], own.frame)
    followed, took = [], []
    for info, camera, _, detector in started:
        clock = time.perf_counter()
        followed.append(track_video(info, camera, detector, video_options, progress))
        took.append(time.perf_counter() - clock)
    clock = time.perf_counter()
    lifted = lifter.lift_cameras({k: (people.tracks, camera) for k, (people, (_, camera, _, _))
                                  in enumerate(zip(followed, started))},
                                 {k: people.layout for k, people in enumerate(followed)},
                                 {k: people.fps for k, people in enumerate(followed)}, one_clock=one_clock,
                                 options=dict(enumerate(each)))
    lifting = time.perf_counter() - clock
    results = []
    for k, ((info, camera, out_dir, _), people, target) in enumerate(zip(started, followed, targets)):
        if isinstance(lifted[k], InputError):
            raise InputError(f"{info.path}: {lifted[k].message}") from None
        clock = time.perf_counter()
        result = _write_video(info, camera, out_dir, target, people, lifted[k], lifter.name, each[k], video_options,
                              overwrite, progress)
        results.append(dataclasses.replace(result, seconds={"people": took[k], "lifting": lifting,
                                                            "writing": time.perf_counter() - clock}))
    return results


def _write_video(info: VideoInfo, camera: Camera, out_dir: Path, targets: dict, people: TrackedPeople, lifted,
                 model: str, options: LiftOptions, video_options: VideoOptions, overwrite: bool,
                 progress: bool) -> VideoResult:
    """One video's people, lifted, written: world, detections, viewer and overlay."""
    dropped = {**people.dropped, **lifted.unliftable}
    world = World(lifted, camera, model, unliftable=lifted.unliftable, rejoined=people.rejoined(),
                  in_part=people.in_part(camera.image_size), floor_evidence=lifted.floor_evidence())
    keypoints = people.keypoints()
    out_dir.mkdir(parents=True, exist_ok=True)
    write_world(targets["world"], world.in_frame(options.frame), overwrite=overwrite)
    write_keypoints_json(targets["keypoints"], keypoints, overwrite)
    write_viewer(targets["viewer"], world.tracks, people.fps, camera, title=f"ray3d: {info.path.name}",
                 overwrite=overwrite)
    if "overlay" in targets:
        write_overlay(info, targets["overlay"], keypoints, world, video_options.start, people.frames_read, overwrite,
                      progress)
    worlds = dict.fromkeys(export_paths(targets["world"], world).values())  # BVH: one file per track
    files = {**targets, "world": next(iter(worlds))} if len(worlds) == 1 else \
        {**{f"world {p.stem.removeprefix('world_')}": p for p in worlds},
         **{k: v for k, v in targets.items() if k != "world"}}
    return VideoResult(keypoints, world, people.frames_read, dropped, files, {})
