"""The cameras a live run follows, each as who is in its frames: a camera's stream read, its people detected,
tracked and lifted frame by frame (``CameraPeople``), and the tracks it lets go lifted again offline on a thread
of their own (``Finisher``), as ``ray3d video`` lifts them. ``LocalCameras`` runs every camera in this process
(the frames of all taken in the order they arrived; files read as fast as processed, in the order of their times);
``ray3d.live.cluster.RayCameras`` runs each in a Ray actor (the same order).
Both give the run the same thing: ``next()`` -> (view, ``FrameResult``), and ``finish()`` at the end, and
``floor``, the pool of what their people show of their one floor (``live.floor.FloorPool``)."""

from __future__ import annotations

import dataclasses
import queue
import threading

from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.geometry.uncertainty import PersonNow
from ray3d.io.world import World
from ray3d.lifting.inputs import prepare_track
from ray3d.lifting.lifter import Lifter
from ray3d.lifting.options import LiftOptions, VideoOptions
from ray3d.lifting.tracks import LiftedTracks
from ray3d.live.floor import CROSSED_JOINTS, FloorPool, TrackFloor
from ray3d.live.people import LivePeople, below_the_stream
from ray3d.live.source import LiveFrame, SourceGroup
from ray3d.video.track import Track


@dataclasses.dataclass
class Finished:
    """A track a camera let go, lifted offline: its ``world`` (one track, world frame), or None and ``why`` it
    was left out, and what it showed of the floor (``floor``; None: nothing)."""

    track: str
    world: World | None
    why: str = ""
    floor: TrackFloor | None = None


@dataclasses.dataclass
class FrameResult:
    """One processed frame of one camera: its ``index``, when it ``arrived`` (this process's monotonic clock),
    the people in it, the tracks let go with it (``ended``), the tracks lifted offline since the last result
    (``done``), from a camera in another process its frames read, dropped and people postponed so far, the
    ``gap`` its stream left just before it, where it was reopened (``LiveFrame.gap``: frame numbers), and every how
    many frames of its stream the camera takes from now on (``stride``: its source is told)."""

    index: int
    arrived: float
    persons: list[PersonNow]
    ended: list[str]
    done: list[Finished]
    counts: tuple[int, int, int] | None = None
    gap: tuple[int, int] | None = None
    stride: int = 1


class Finisher:
    """Lifts the tracks a camera lets go, one by one on a thread of its own (a track shorter than
    ``min_track_s`` is left out); ``take()`` hands over what is done so far. ``floor``: the run's pool of what
    its cameras' people showed of the floor (``live.floor.FloorPool``; None: this camera's own)."""

    def __init__(self, lifter: Lifter, camera: Camera, layout: str, fps: float, lift_options: LiftOptions,
                 min_track_s: float, floor: FloorPool | None = None):
        self.lifter, self.camera, self.layout, self.fps = lifter, camera, layout, fps
        self.lift_options, self.min_track_s = lift_options, min_track_s
        # What the people seen so far, by every camera of the run, say of the floor (``refine.ankle_plane``), each
        # later track lifted with it: the estimate refines as people pass.
        self.floor = floor if floor is not None else FloorPool()
        self._done: list[Finished] = []
        self._lock = threading.Lock()
        self._queue: queue.Queue = queue.Queue(maxsize=64)
        self._thread = threading.Thread(target=self._run, name="finisher", daemon=True)
        self._thread.start()

    def put(self, track: Track) -> None:
        self._queue.put(track)

    def take(self) -> list[Finished]:
        with self._lock:
            done, self._done = self._done, []
        return done

    def close(self) -> list[Finished]:
        """Waits for every track put; what is not taken yet."""
        self._queue.put(None)
        self._thread.join()
        return self.take()

    def _run(self) -> None:
        below_the_stream()
        while (track := self._queue.get()) is not None:
            finished = self._finish(track)
            with self._lock:
                self._done.append(finished)

    def _finish(self, track: Track) -> Finished:
        if (short := track.too_short(self.fps, self.min_track_s)) is not None:
            return Finished(track.id, None, short)
        try:
            options = dataclasses.replace(self.lift_options,
                                          seen_before=(*self.lift_options.seen_before, *self.floor.evidence()))
            lifted = self.lifter.lift_tracks({track.id: track.as_detections()}, self.camera, self.layout,
                                             self.fps, **options.lift_arguments())
            # The floor is observed from everybody the run's cameras have seen so far (the latest people,
            # bounded), and from what earlier runs showed (the pool's, and the options').
            evidence = lifted.floor_evidence()
            self.floor.add(evidence)
            floor = self._track_floor(track, lifted, evidence)
        except InputError as err:
            return Finished(track.id, None, err.message)
        except Exception as err:  # one person's failure must not stop the others being written
            return Finished(track.id, None, f"could not be lifted ({type(err).__name__}: {err})")
        rejoined = {track.id: [rejoin.to_dict() for rejoin in track.rejoins]} if track.rejoins else {}
        return Finished(track.id, World(lifted, self.camera, self.lifter.name, rejoined=rejoined).in_frame("world"),
                        floor=floor)

    def _track_floor(self, track: Track, lifted: LiftedTracks, evidence: tuple) -> TrackFloor | None:
        """What the track showed of the floor, with the rays of its pelvis and ankles, to be crossed with another
        camera's track where the run's join finds them one person (None: lifted unrefined, no floor to tell)."""
        if lifted.ankle_plane is None:
            return None
        frames, pixels, confidences = track.as_detections().dense(track.id)
        prepared = prepare_track(pixels, self.camera, confidences, self.fps, self.layout, None,
                                 self.lifter.input_skeleton)
        joints = list(CROSSED_JOINTS)
        return TrackFloor(evidence, self.layout, lifted.ankle_plane.contact_m, self.camera.center, frames,
                          prepared.rays[:, joints].astype("float32"), ~prepared.missing[:, joints], self.fps)


class CameraPeople:
    """One camera: its frames -> its people (``LivePeople``), the tracks it lets go lifted (``Finisher``)."""

    def __init__(self, camera: Camera, detector, lifter: Lifter, fps: float, keep: int | None,
                 lift_options: LiftOptions, following: VideoOptions, id_prefix: str = "",
                 floor: FloorPool | None = None, carried=()):
        """``keep``: the frames its stream keeps (the detector's deadline), None for a stream that waits for it;
        ``following``: how its people are followed (``max_gap_s``, ``rejoin_s``, ``min_track_s``); ``id_prefix``:
        written before each of its track ids (a run's number); ``floor``: the run's floor pool (``Finisher``);
        ``carried``: the people in view when the run before was cut off, whose ids its first tracks may take up
        (``FloorTracker``). The lifter's small-batch path is made here, before the first frame is taken (it pauses
        0.2 s; the stream may be running)."""
        lifter.prepare_small_batches()
        self._following = dict(camera=camera, detector=detector, lifter=lifter, fps=fps, floor=lift_options.floor,
                               max_gap_s=following.max_gap_s, rejoin_s=following.rejoin_s, deadline_frames=keep)
        self.id_prefix, self.gaps = id_prefix, 0
        self.people = LivePeople(**self._following, id_prefix=id_prefix, carried=carried)
        self.finisher = Finisher(lifter, camera, detector.layout, fps, lift_options, following.min_track_s, floor)
        self.detector = detector

    def postponed(self) -> int:
        """People the detector left for the next frame so far, to keep up."""
        return getattr(self.detector, "postponed", 0)

    def process(self, frame: LiveFrame) -> FrameResult:
        cut = self._after_gap() if frame.gap is not None else []
        persons, finished = self.people.update(frame)
        for track in finished:
            self.finisher.put(track)
        return FrameResult(frame.index, frame.arrived, persons, [t.id for t in cut + finished],
                           self.finisher.take(), gap=frame.gap, stride=self.people.stride)

    def _after_gap(self) -> list:
        """The stream was down: everybody followed before it is let go (nobody is followed, or counted, across a
        gap) and the tracks after it are numbered apart."""
        cut = self._let_go()
        self.gaps += 1
        self.people = LivePeople(**self._following, id_prefix=f"{self.id_prefix}g{self.gaps}-")
        return cut

    def finish(self) -> tuple[list[tuple[str, int]], list[Finished]]:
        """Everybody still in view let go: (track, last frame) of each, and every track lifted not yet taken."""
        in_view = self._let_go()
        return [(t.id, t.frames[-1]) for t in in_view], self.finisher.close()

    def _let_go(self) -> list:
        """Everybody in view let go, each track handed to be lifted whole: those tracks."""
        self.people.close()
        in_view = self.people.in_view()
        for track in in_view:
            self.finisher.put(track)
        return in_view


class LocalCameras:
    """Every camera in this process: the frames of all taken from one ``SourceGroup`` in the order they arrived
    (files read as fast as they are processed: in the order of their times)."""

    def __init__(self, group: SourceGroup, cameras: list[Camera], detectors: list, lifter: Lifter,
                 lift_options: LiftOptions | list[LiftOptions], following: VideoOptions, id_prefix: str = "",
                 carried=()):
        """``lift_options``: one for every camera, or each camera's own (its floor), as on Ray; ``id_prefix``:
        before every track id (a run's number: ids unique across the runs of a store); ``carried``: the people in
        view of the one camera when the run before was cut off (``CameraPeople``)."""
        self.group, self.cameras, self.name = group, cameras, group.name
        self.fps = [source.fps for source in group.sources]
        self.sources = [source.name for source in group.sources]
        self.names = [camera.name or source.name for camera, source in zip(cameras, group.sources)]
        options = lift_options if isinstance(lift_options, list) else [lift_options] * len(cameras)
        # One site, one world frame, one floor: every camera's lifts draw on every camera's people.
        self.floor = FloorPool()
        self.views = [CameraPeople(c, d, lifter, source.fps, source.deadline_frames, o, following, id_prefix,
                                   self.floor, carried if len(cameras) == 1 else ())
                      for c, d, source, o in zip(cameras, detectors, group.sources, options)]

    def set_clocks(self, offsets_s: list[float]) -> None:
        """Each camera's clock ahead of the first's (``SourceGroup.offsets_s``)."""
        self.group.offsets_s = list(offsets_s)

    def next(self) -> tuple[int, FrameResult] | None:
        taken = self.group.next()
        if taken is None:
            return None
        view, frame = taken
        result = self.views[view].process(frame)
        self.group.sources[view].stride = result.stride
        return view, result

    def finish(self) -> list[tuple[list[tuple[str, int]], list[Finished]]]:
        return [view.finish() for view in self.views]

    @property
    def read(self) -> int:
        return self.group.read

    @property
    def dropped(self) -> int:
        return self.group.dropped

    @property
    def postponed(self) -> int:
        return sum(view.postponed() for view in self.views)

    def close(self) -> None:
        self.group.close()
