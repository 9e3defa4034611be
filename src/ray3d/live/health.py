"""Whether a live run keeps up with its streams (``Keeping``): per camera, the share of its frames dropped over the
last ``window_s`` seconds of stream time, and the people its detector left for the next frame to keep its deadline;
a stretch in which the share is above ``BEHIND_SHARE``, or more than ``POSTPONED_PER_FRAME`` people a frame were
left (in either case more than one frame or person: a single one is a hiccup), is one whose counts are uncertain (people
crossing a line or entering a zone between two processed frames, or not looked at in them, may be missed). Each stretch
is said on stderr as it begins and as it ends, shown on the page (``state()``), published on MQTT and recorded in the
store (``RunRecorder.behind``: its start, end and share dropped), whose report shades it.

The tracker, the lifting's smoothing and the site's rules already see the real time between the frames processed:
each frame carries its own number in the stream (``LiveFrame.index``), and the tracker (``FloorTracker.update``),
the smoother's step and the site's events (``SiteMonitor.update``) are given that number, not a count of frames
processed."""

from __future__ import annotations

import dataclasses
import sys
from collections import deque
from collections.abc import Callable

BEHIND_SHARE = 0.02  # more than this share of a window's frames dropped: falling behind
# More people than this a frame left for the next one (the detector keeping its deadline): falling behind too; on
# vtest.avi with a core kept busy, 1.5 a frame while 4.7 % of frames were dropped, and the events 24 % fewer.
POSTPONED_PER_FRAME = 0.05
WINDOW_S = 10.0


@dataclasses.dataclass
class Stretch:
    """A stretch of stream time (seconds, the run's clock) in which camera ``camera`` could not keep up: from
    ``from_s`` to ``to_s`` (None while it lasts), its frames read and dropped and the people left for the next frame
    over it."""

    camera: str
    from_s: float
    to_s: float | None
    read: int
    dropped: int
    postponed: int = 0

    @property
    def share(self) -> float:
        return self.dropped / self.read if self.read > 0 else 0.0

    def as_dict(self) -> dict:
        return {"camera": self.camera, "from_s": round(self.from_s, 2),
                "to_s": None if self.to_s is None else round(self.to_s, 2),
                "dropped_percent": round(100 * self.share, 1),
                "postponed_per_frame": round(self.postponed / self.read, 2) if self.read > 0 else 0.0}


class Keeping:
    """Per camera (``names``, each stream's ``fps``): ``observe(view, time_s, read, dropped, postponed)`` with each
    processed frame's time on the run's clock and its stream's frames read and dropped and people left for the next
    frame so far. ``report`` is told of each
    stretch's start and end; ``recorded(stretch)`` of each stretch once it has ended (the store)."""

    def __init__(self, names: list[str], fps: list[float], window_s: float = WINDOW_S, share: float = BEHIND_SHARE,
                 report: Callable[[str], None] = lambda line: print(line, file=sys.stderr, flush=True),
                 recorded: Callable[[Stretch], None] = lambda stretch: None):
        self.names, self.fps, self.window_s, self.limit = list(names), list(fps), float(window_s), float(share)
        self.report, self.recorded = report, recorded
        self._samples = [deque() for _ in self.names]  # (time_s, read, dropped, postponed): the window and one before
        self._now = [0.0 for _ in self.names]  # each camera's share dropped over the last window
        self._open: list[tuple[Stretch, tuple] | None] = [None for _ in self.names]  # with the counts at its start
        self._last_drop: list[tuple | None] = [None for _ in self.names]  # the last loss's (time_s, read, dropped, ...)
        self.stretches: list[Stretch] = []  # every stretch, ended or not, in the order they began
        self.strides = [1 for _ in self.names]  # every how many frames each camera takes now

    def observe(self, view: int, time_s: float, read: int, dropped: int, postponed: int = 0, stride: int = 1) -> None:
        if stride != self.strides[view]:
            rate = self.fps[view] / stride
            self.report(f"camera {self.names[view]}: " + (
                f"the machine cannot follow every frame: 1 frame in {stride} taken from {time_s:.1f} s "
                f"({rate:.1f} frames/s), everybody still followed" if stride > 1 else
                f"every frame taken again from {time_s:.1f} s"))
            self.strides[view] = stride
        samples = self._samples[view]
        sample = (float(time_s), int(read), int(dropped), int(postponed))
        if samples and (dropped > samples[-1][2] or postponed > samples[-1][3]):
            self._last_drop[view] = sample
        samples.append(sample)
        while len(samples) > 2 and samples[1][0] <= time_s - self.window_s:
            samples.popleft()
        first = samples[0]
        # Over a whole window's frames at least: one frame dropped at the start is not 50 % of two.
        frames = max(read - first[1], self.window_s * self.fps[view], 1.0)
        lost, waiting = dropped - first[2], postponed - first[3]
        share = self._now[view] = lost / frames
        left = waiting / frames
        # One frame dropped or one person left once is a hiccup (a busy moment), not falling behind.
        behind = (share > self.limit and lost > 1) or (left > POSTPONED_PER_FRAME and waiting > 1)
        opened = self._open[view]
        if opened is None and behind:
            # It began at the frame processed before the window's first loss.
            begun = next(before for before, after in zip(samples, list(samples)[1:])
                         if after[2] > before[2] or after[3] > before[3])
            stretch = Stretch(self.names[view], begun[0], None, read - begun[1], dropped - begun[2],
                              postponed - begun[3])
            self._open[view] = (stretch, begun)
            self.stretches.append(stretch)
            self.report(f"camera {stretch.camera}: falling behind: {100 * share:.0f} % of frames dropped and "
                        f"{left:.2f} people a frame left for the next over the last {self.window_s:g} s; counts from "
                        "now on are uncertain")
        elif opened is not None:
            stretch, begun = opened
            stretch.read, stretch.dropped, stretch.postponed = read - begun[1], dropped - begun[2], postponed - begun[3]
            if not behind:
                self._end(view, "keeping up again")

    def _end(self, view: int, how: str) -> None:
        """The stretch ended at the last frame dropped (at the run's end: its last frame); its share is of the
        frames read up to then."""
        stretch, begun = self._open[view]
        self._open[view] = None
        last_s, read, dropped, postponed = self._last_drop[view] if how != "the run ended" else self._samples[view][-1]
        stretch.to_s = max(stretch.from_s, last_s)
        stretch.read, stretch.dropped, stretch.postponed = read - begun[1], dropped - begun[2], postponed - begun[3]
        self.report(f"camera {stretch.camera}: {how} after {stretch.to_s - stretch.from_s:.0f} s falling behind "
                    f"({100 * stretch.share:.0f} % of its frames dropped, {stretch.postponed} people left for the next "
                    f"frame, from {stretch.from_s:.1f} s to {stretch.to_s:.1f} s of the stream); counts in that time "
                    "are uncertain")
        self.recorded(stretch)

    def finish(self) -> None:
        """Every stretch still open ended at its camera's last frame."""
        for view, opened in enumerate(self._open):
            if opened is not None:
                self._end(view, "the run ended")

    @property
    def behind(self) -> bool:
        return any(opened is not None for opened in self._open)

    def state(self) -> dict:
        """For the page and MQTT: whether any camera falls behind now, each camera's share dropped over the last
        window (%), every how many frames each takes now, the stretches now and before."""
        return {"falling_behind": self.behind, "window_s": self.window_s,
                "dropped_percent": {name: round(100 * share, 1) for name, share in zip(self.names, self._now)},
                "frames_apart": dict(zip(self.names, self.strides)),
                "stretches": [stretch.as_dict() for stretch in self.stretches]}
