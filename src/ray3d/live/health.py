"""Whether a live run keeps up with its streams (``Keeping``): per camera, the share of its frames dropped over the
last ``window_s`` seconds of stream time; a stretch in which it is above ``BEHIND_SHARE`` is one whose counts are
uncertain (people crossing a line or entering a zone between two processed frames may be missed). Each stretch is
said on stderr as it begins and as it ends, shown on the page (``state()``), published on MQTT and recorded in the
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
WINDOW_S = 10.0


@dataclasses.dataclass
class Stretch:
    """A stretch of stream time (seconds, the run's clock) in which camera ``camera`` could not keep up: from
    ``from_s`` to ``to_s`` (None while it lasts), its frames read and dropped over it."""

    camera: str
    from_s: float
    to_s: float | None
    read: int
    dropped: int

    @property
    def share(self) -> float:
        return self.dropped / self.read if self.read > 0 else 0.0

    def as_dict(self) -> dict:
        return {"camera": self.camera, "from_s": round(self.from_s, 2),
                "to_s": None if self.to_s is None else round(self.to_s, 2),
                "dropped_percent": round(100 * self.share, 1)}


class Keeping:
    """Per camera (``names``, each stream's ``fps``): ``observe(view, time_s, read, dropped)`` with each processed
    frame's time on the run's clock and its stream's frames read and dropped so far. ``report`` is told of each
    stretch's start and end; ``recorded(stretch)`` of each stretch once it has ended (the store)."""

    def __init__(self, names: list[str], fps: list[float], window_s: float = WINDOW_S, share: float = BEHIND_SHARE,
                 report: Callable[[str], None] = lambda line: print(line, file=sys.stderr, flush=True),
                 recorded: Callable[[Stretch], None] = lambda stretch: None):
        self.names, self.fps, self.window_s, self.limit = list(names), list(fps), float(window_s), float(share)
        self.report, self.recorded = report, recorded
        self._samples = [deque() for _ in self.names]  # (time_s, read, dropped), the window's and one before it
        self._now = [0.0 for _ in self.names]  # each camera's share dropped over the last window
        self._open: list[tuple[Stretch, int, int] | None] = [None for _ in self.names]  # with its counts at start
        self._last_drop: list[tuple[float, int, int] | None] = [None for _ in self.names]  # (time_s, read, dropped)
        self.stretches: list[Stretch] = []  # every stretch, ended or not, in the order they began

    def observe(self, view: int, time_s: float, read: int, dropped: int) -> None:
        samples = self._samples[view]
        if samples and dropped > samples[-1][2]:
            self._last_drop[view] = (float(time_s), int(read), int(dropped))
        samples.append((float(time_s), int(read), int(dropped)))
        while len(samples) > 2 and samples[1][0] <= time_s - self.window_s:
            samples.popleft()
        first = samples[0]
        # Over a whole window's frames at least: one frame dropped at the start is not 50 % of two.
        frames = max(read - first[1], self.window_s * self.fps[view], 1.0)
        share = self._now[view] = (dropped - first[2]) / frames
        opened = self._open[view]
        if opened is None and share > self.limit:
            # It began at the frame processed before the window's first drop.
            begun = next(before for before, after in zip(samples, list(samples)[1:]) if after[2] > before[2])
            stretch = Stretch(self.names[view], begun[0], None, read - begun[1], dropped - begun[2])
            self._open[view] = (stretch, begun[1], begun[2])
            self.stretches.append(stretch)
            self.report(f"camera {stretch.camera}: falling behind: {100 * share:.0f} % of frames dropped over the "
                        f"last {self.window_s:g} s; counts from now on are uncertain")
        elif opened is not None:
            stretch, read_at, dropped_at = opened
            stretch.read, stretch.dropped = read - read_at, dropped - dropped_at
            if share <= self.limit:
                self._end(view, "keeping up again")

    def _end(self, view: int, how: str) -> None:
        """The stretch ended at the last frame dropped (at the run's end: its last frame); its share is of the
        frames read up to then."""
        stretch, read_at, dropped_at = self._open[view]
        self._open[view] = None
        last_s, read, dropped = self._last_drop[view] if how != "the run ended" else self._samples[view][-1]
        stretch.to_s = max(stretch.from_s, last_s)
        stretch.read, stretch.dropped = read - read_at, dropped - dropped_at
        self.report(f"camera {stretch.camera}: {how} after {stretch.to_s - stretch.from_s:.0f} s falling behind "
                    f"({100 * stretch.share:.0f} % of its frames dropped from {stretch.from_s:.1f} s to "
                    f"{stretch.to_s:.1f} s of the stream); counts in that time are uncertain")
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
        window (%), the stretches now and before."""
        return {"falling_behind": self.behind, "window_s": self.window_s,
                "dropped_percent": {name: round(100 * share, 1) for name, share in zip(self.names, self._now)},
                "stretches": [stretch.as_dict() for stretch in self.stretches]}
