"""What a live run's cameras give, brought together (``Views``): each camera's finished people appended to its
world file and the store, and with several cameras their people joined into world people (``LiveFusion``) on the
first camera's clock, who each of them was appended to ``joined.jsonl`` as they leave and kept (``joined``: the
world file is fused by that join). What each camera's people showed of the run's one floor is written to the store as
they are lifted, the ankles of people two cameras saw at once are crossed where the join decides who they were
(``live.floor.JoinedAnkles``) and added to the run's floor pool, and the pool starts with what earlier runs of
the store showed of these cameras' floor."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ray3d.errors import InputError
from ray3d.fusion.live import WAIT_S, LiveFusion
from ray3d.geometry.uncertainty import PersonNow
from ray3d.io.world import append_world_csv
from ray3d.live.cameras import FrameResult
from ray3d.live.floor import JoinedAnkles, floor_shown
from ray3d.refine.ankle_plane import AnklePlane
from ray3d.site.analytics import stature_class


class Views:
    """What the cameras give, brought together: each camera's finished people appended to its world file; with
    several, their people joined into world people (``LiveFusion``) on the first camera's clock, each frame held
    until it is settled (``HeldFrames``)."""

    def __init__(self, cameras, out_dir: Path, offsets_s: list[float] | None, recorder=None):
        self.cameras, self.several, self.recorder = cameras, len(cameras.cameras) > 1, recorder
        self.fps = cameras.fps[0]
        count = len(cameras.cameras)
        self.offsets_s = list(offsets_s) if offsets_s is not None else [0.0] * count
        if len(self.offsets_s) != count:
            raise InputError(f"offsets: {len(self.offsets_s)} given for {count} cameras", ("offsets",))
        cameras.set_clocks(self.offsets_s)  # files read as fast as processed are taken in time order on these
        self.world_paths = [out_dir / "world.csv"] if not self.several else \
            [out_dir / f"camera{k + 1}_{_file_name(name)}" / "world.csv" for k, name in enumerate(cameras.names)]
        self.joined_path = out_dir / JOINED_FILE
        for path in self.world_paths + ([self.joined_path] if self.several else []):
            if path.exists() and not (recorder and recorder.continues):
                raise InputError(f"{path}: exists; ray3d live never writes over an output", ("out",))
            path.parent.mkdir(parents=True, exist_ok=True)
        self.fusion = LiveFusion(cameras.cameras, 1.0 / min(cameras.fps),
                                 id_prefix=recorder.id_prefix if recorder else "") if self.several else None
        self.written, self.left_out = 0, {}
        self.joined: dict[str, list[tuple[int, str]]] = {}  # who each world person that left was
        self.label = " + ".join(str(name) for name in cameras.names)  # who saw the world's people
        self.held = HeldFrames(self.fps, int(np.ceil((WAIT_S + 2.0 / min(cameras.fps)) * self.fps))) \
            if self.several else None
        # The run's one floor: the cameras' pool (``live.floor.FloorPool``) from what earlier runs showed of
        # these cameras where they stand now, the people two of them saw at once crossed as the join names them,
        # and each camera's latest decision, for the page.
        self.floor = getattr(cameras, "floor", None)
        if self.floor is not None and recorder is not None:
            self.floor.remember(recorder.remembered_floor(list(zip(cameras.names,
                                                                   (c.center for c in cameras.cameras)))))
        self.ankles = JoinedAnkles(self._ticks) if self.several else None
        self.planes: dict[int, AnklePlane] = {}

    def take(self, view: int, result: FrameResult) -> tuple[list[tuple], list[PersonNow], list[str]]:
        """This camera's processed frame -> the frames settled for the site's events (each its number on the first
        camera's clock and its people, in order), the people now and those who left. With several cameras a frame
        is settled once who everybody in it is has been decided, with what each saw before that (``WAIT_S`` and
        two frames later): a person's first moments are counted as one camera counts them."""
        self._write(view, result.done)
        if self.recorder is not None:
            if result.gap is not None:  # on the stream's clock, as the events are
                before, after = (self.recorder.origin + self.time_s(view, index) for index in result.gap)
                self.recorder.gap(self.cameras.names[view], before, after, "the stream was down")
        if not self.several:
            return [(result.index, result.persons)], result.persons, result.ended
        time_s = self.time_s(view, result.index)
        for track in result.ended:
            self.fusion.finished(view, track)
        persons = self.fusion.update(view, time_s, result.persons)
        settled = self.held.newest(time_s, persons, self.fusion.decided)
        return settled, persons, self._ended(time_s)

    def recorded(self, view: int, result: FrameResult) -> None:
        """This camera's processed frame recorded, once its events are handed to the store: a run cut off after
        the store's commit is taken up at the next frame, with every event of this one."""
        if self.recorder is not None:
            self.recorder.progress(self.cameras.sources[view], result.index, self.time_s(view, result.index))

    def finish(self) -> tuple[list[tuple], list[tuple[str, int]]]:
        """Everybody still in view handed over: the frames not settled yet, in order, and who leaves (person, the
        first camera's frame they were last seen in)."""
        leaving = []
        for view, (in_view, done) in enumerate(self.cameras.finish()):
            self._write(view, done)
            for track, last_frame in in_view:
                if self.several:
                    self.fusion.finished(view, track)
                else:
                    leaving.append((track, last_frame))
        if not self.several:
            return [], leaving
        leaving = [(n, int(round(seen_s * self.fps))) for n, seen_s in self._ended(np.inf, seen=True)]
        return self.held.last(self.fusion.decided), leaving

    def _ended(self, time_s: float, seen: bool = False) -> list:
        """``LiveFusion.ended``, and who each of those people was kept and appended to the join's file."""
        gone = self.fusion.ended(time_s, seen)
        for _, members in self.fusion.joined:
            self._seen_twice(self.ankles.joined(members))
        self.joined.update((person, [(int(view), str(track)) for view, track in members])
                           for person, members in self.fusion.joined)
        if self.fusion.joined:
            with self.joined_path.open("a") as handle:
                handle.writelines(json.dumps({"person": person, "tracks": [list(m) for m in members]}) + "\n"
                                  for person, members in self.fusion.joined)
            self.fusion.joined.clear()
        return gone

    def time_s(self, view: int, index: int) -> float:
        """A frame of camera ``view`` on the first camera's clock (seconds)."""
        return index / self.cameras.fps[view] - self.offsets_s[view]

    def _ticks(self, view: int, frames: np.ndarray) -> np.ndarray:
        """Frames of camera ``view`` as the first camera's frames (whole ones): what two cameras saw at once."""
        return np.round((np.asarray(frames) / self.cameras.fps[view] - self.offsets_s[view]) * self.fps).astype(int)

    def floor_lines(self) -> list[dict]:
        """Each camera's floor as its latest lift decided it (``live.floor.floor_shown``), for the page."""
        return [floor_shown(self.cameras.names[view], plane) for view, plane in sorted(self.planes.items())]

    def _seen_twice(self, found: list) -> None:
        """People two cameras saw at once (``JoinedAnkles``): to the run's floor pool and each camera's record."""
        for crossing, pair in found:
            if self.floor is not None:
                self.floor.add((crossing,))
            for view in pair if self.recorder is not None else ():
                self.recorder.floor(self.cameras.names[view], self.cameras.cameras[view].center, (crossing,))

    def _floor_of(self, view: int, finished) -> None:
        """What a lifted track showed of the floor: to the store, to be crossed with another camera's track of
        the same person, and its camera's decision to the page."""
        if self.ankles is not None:
            self._seen_twice(self.ankles.lifted(view, finished.track, finished.floor))
        if finished.floor is not None and self.recorder is not None:
            self.recorder.floor(self.cameras.names[view], finished.floor.centre, finished.floor.evidence,
                                finished.floor.keypoints)
        track = next(iter(finished.world.tracks.values())) if finished.world is not None else None
        if track is not None and (track.refinement or {}).get("ankle_plane"):
            self.planes[view] = AnklePlane.from_summary(track.refinement["ankle_plane"])

    def _write(self, view: int, done: list) -> None:
        for finished in done:
            self._floor_of(view, finished)
            if finished.world is None:
                self.left_out[f"{view + 1}:{finished.track}" if self.several else finished.track] = finished.why
                continue
            append_world_csv(self.world_paths[view], finished.world)
            self.written += 1
            if self.recorder is not None:
                track = next(iter(finished.world.tracks.values()))
                refinement = track.refinement or {}
                stature = refinement.get("stature_m")
                self.recorder.person(finished.track, self.time_s(view, int(track.frames[0])),
                                     self.time_s(view, int(track.frames[-1])), stature,
                                     stature_class(stature, refinement.get("stature_interval_m")),
                                     len((finished.world.rejoined or {}).get(finished.track, ())),
                                     self.cameras.names[view])


class HeldFrames:
    """Several cameras' frames not settled yet, {frame: {person: PersonNow}} on the first camera's clock (``fps``),
    held until who everybody in them is has been decided (``LiveFusion``: ``WAIT_S`` at most) and every camera's view
    of them is in: ``hold_frames`` behind the newest frame any camera has given."""

    def __init__(self, fps: float, hold_frames: int):
        self.fps, self.hold_frames = fps, hold_frames
        self._held: dict[int, dict[str, PersonNow]] = {}
        self._settled_until = -1  # the last frame settled
        self._newest = -1  # the newest frame any camera has given

    def newest(self, time_s: float, persons: list[PersonNow], decided: list) -> list[tuple]:
        """A camera's people now (at ``time_s``) and what tracks saw before who they were was ``decided``, held;
        the frames settled by them, in order: (frame, its people)."""
        # The people now are every camera's latest answers: a camera's frame that comes in after another's later
        # one updates the newest frame (an older one would go back in time for the other camera's people).
        index = self._newest = max(self._newest, int(round(time_s * self.fps)))
        self._hold(index, persons)
        self._hold_decided(decided)
        return self._settle(index - self.hold_frames)

    def last(self, decided: list) -> list[tuple]:
        """Every frame held settled, in order, with what was ``decided`` last."""
        self._hold_decided(decided)
        return self._settle(np.inf)

    def _hold(self, index: int, persons: list[PersonNow], replace: bool = True) -> None:
        """``persons`` in frame ``index`` until it is settled (too late for a frame settled already); without
        ``replace``, only where the frame has not got that person."""
        if index > self._settled_until:
            frame = self._held.setdefault(index, {})
            for person in persons:
                if replace or person.track not in frame:
                    frame[person.track] = person

    def _hold_decided(self, decided: list) -> None:
        """What tracks saw before who they were was decided (``LiveFusion.decided``: (time_s, PersonNow) pairs,
        taken from the list), into the held frames."""
        for at, now in decided:
            self._hold(int(round(at * self.fps)), [now], replace=False)
        decided.clear()

    def _settle(self, until: float) -> list[tuple]:
        """The held frames up to ``until``, in order: (frame, its people)."""
        ready = sorted(index for index in self._held if index <= until)
        if ready:
            self._settled_until = ready[-1]
        return [(index, list(self._held.pop(index).values())) for index in ready]


JOINED_FILE = "joined.jsonl"


def _file_name(name: str) -> str:
    """A camera's or a stream's name as a folder name."""
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in Path(str(name)).stem) or "camera"
