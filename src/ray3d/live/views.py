"""What a live run's cameras give, brought together (``Views``): each camera's finished people appended to its
world file and the store, and with several cameras their people joined into world people (``LiveFusion``) on the
first camera's clock."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ray3d.errors import InputError
from ray3d.fusion.live import LiveFusion
from ray3d.io.world import append_world_csv
from ray3d.live.cameras import FrameResult
from ray3d.geometry.uncertainty import PersonNow
from ray3d.site.analytics import stature_class


class Views:
    """What the cameras give, brought together: each camera's finished people appended to its world file; with
    several, their people joined into world people (``LiveFusion``) on the first camera's clock."""

    def __init__(self, cameras, out_dir: Path, offsets_s: list[float] | None, recorder=None):
        self.cameras, self.several, self.recorder = cameras, len(cameras.cameras) > 1, recorder
        self.fps = cameras.fps[0]
        count = len(cameras.cameras)
        self.offsets_s = list(offsets_s) if offsets_s is not None else [0.0] * count
        if len(self.offsets_s) != count:
            raise InputError(f"offsets: {len(self.offsets_s)} given for {count} cameras", ("offsets",))
        self.world_paths = [out_dir / "world.csv"] if not self.several else \
            [out_dir / f"camera{k + 1}_{_file_name(name)}" / "world.csv" for k, name in enumerate(cameras.names)]
        for path in self.world_paths:
            if path.exists() and not (recorder and recorder.continues):
                raise InputError(f"{path}: exists; ray3d live never writes over an output", ("out",))
            path.parent.mkdir(parents=True, exist_ok=True)
        self.fusion = LiveFusion(cameras.cameras, 1.0 / min(cameras.fps),
                                 id_prefix=recorder.id_prefix if recorder else "") if self.several else None
        self.written, self.left_out = 0, {}
        self.label = " + ".join(str(name) for name in cameras.names)  # who saw the world's people
        self._pending: tuple | None = None  # several cameras: the frame whose views are still coming in

    def take(self, view: int, result: FrameResult) -> tuple[tuple | None, list[PersonNow], list[str]]:
        """This camera's processed frame -> a frame settled for the site's events (its number on the first
        camera's clock and its people; None while it is not), the people now and those who left. With several
        cameras a frame is settled when the next begins: by then every camera's view of it is in."""
        self._write(view, result.done)
        if self.recorder is not None:
            self.recorder.progress(self.cameras.sources[view], result.index, self.time_s(view, result.index))
            if result.gap is not None:  # on the stream's clock, as the events are
                before, after = (self.recorder.origin + self.time_s(view, index) for index in result.gap)
                self.recorder.gap(self.cameras.names[view], before, after, "the stream was down")
        if not self.several:
            return (result.index, result.persons), result.persons, result.ended
        time_s = result.index / self.cameras.fps[view] - self.offsets_s[view]
        for track in result.ended:
            self.fusion.finished(view, track)
        persons = self.fusion.update(view, time_s, result.persons)
        index, settled = int(round(time_s * self.fps)), None
        if self._pending is None or index > self._pending[0]:
            settled, self._pending = self._pending, (index, persons)
        else:
            self._pending = (self._pending[0], persons)
        return settled, persons, self.fusion.ended(time_s)

    def finish(self) -> tuple[tuple | None, list[tuple[str, int]]]:
        """Everybody still in view handed over: the last frame not settled yet (None if none) and who leaves
        (person, the first camera's frame they were last seen in)."""
        leaving = []
        for view, (in_view, done) in enumerate(self.cameras.finish()):
            self._write(view, done)
            for track, last_frame in in_view:
                if self.several:
                    self.fusion.finished(view, track)
                else:
                    leaving.append((track, last_frame))
        if self.several:
            leaving = [(n, int(round(seen_s * self.fps))) for n, seen_s in self.fusion.ended(np.inf, seen=True)]
        return self._pending, leaving

    def time_s(self, view: int, index: int) -> float:
        """A frame of camera ``view`` on the first camera's clock (seconds)."""
        return index / self.cameras.fps[view] - self.offsets_s[view]

    def _write(self, view: int, done: list) -> None:
        for finished in done:
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


def _file_name(name: str) -> str:
    """A camera's or a stream's name as a folder name."""
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in Path(str(name)).stem) or "camera"
