"""Frames as they arrive: a video file played at its own rate, a camera device or a network stream (anything
OpenCV / FFmpeg opens: RTSP, HTTP), read on a thread of their own into a buffer that holds only the newest ``keep``
frames (2 by default). A frame pushed out by newer ones before it was taken is dropped on purpose and counted, so
whoever takes frames is never behind the stream by more than ``keep`` frames, however slow they are; the second frame
absorbs a short burst of slow frames (a crowded moment) without a drop. Whoever cannot keep up for longer asks for
every k-th frame only (``stride``): the others are skipped evenly rather than dropped where they pile up."""

from __future__ import annotations

import collections
import dataclasses
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import cv2
import numpy as np

from ray3d.errors import InputError


@dataclasses.dataclass(frozen=True)
class LiveFrame:
    """A frame: its number in the stream (from 0), the (H, W, 3) uint8 RGB image and when it was read
    (``time.monotonic()``); the first frame after the stream was reopened carries the ``gap`` it leaves (the
    numbers of the last frame before and of this one: the gap on the stream's clock, as its events are)."""

    index: int
    image: np.ndarray
    arrived: float
    gap: tuple[int, int] | None = None


class StreamStalled(Exception):
    """No frame arrived for the stall timeout while the stream had not ended."""

    def __init__(self, source: str, seconds: float):
        super().__init__(f"{source}: no frame for {seconds:g} s: the stream stalled")
        self.message = str(self)


def _device_or_location(source: str) -> int | str:
    return int(source) if source.isdigit() else source


def _opened(source: str, skip: int = 0, read_timeout_s: float | None = None) -> tuple[cv2.VideoCapture, np.ndarray,
                                                                                     float]:
    """The capture, its first frame (BGR; ``skip`` frames on) and its frame rate (0 when it does not say). A
    network stream gives up a read after ``read_timeout_s`` (OpenCV's default: 30 s), so that a reader of a stream
    gone silent ends soon after it is closed."""
    location = _device_or_location(source)
    if read_timeout_s is not None and isinstance(location, str) and "://" in location:
        timeout_ms = int(max(1.0, read_timeout_s) * 1000)
        capture = cv2.VideoCapture(location, cv2.CAP_ANY, [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, max(timeout_ms, 10_000),
                                                           cv2.CAP_PROP_READ_TIMEOUT_MSEC, timeout_ms])
    else:
        capture = cv2.VideoCapture(location)
    if not capture.isOpened():
        capture.release()
        raise InputError(f"{source}: cannot be opened as a video file, camera device or stream", ("source",))
    grabbed = 0
    while grabbed < skip and capture.grab():  # frame by frame: seeking a compressed file lands on key frames only
        grabbed += 1
    ok, first = capture.read()
    if not ok:
        capture.release()
        if skip and grabbed > 0:
            raise InputError(f"{source}: nothing left to follow: its {grabbed} frames were all taken by an earlier "
                             f"run (the store's record takes it up at frame {skip})", ("source",))
        raise InputError(f"{source}: no frame could be read: not a video, or an empty one", ("source",))
    return capture, first, float(capture.get(cv2.CAP_PROP_FPS) or 0.0)


def _frames_of(capture: cv2.VideoCapture, first: np.ndarray) -> Iterator[np.ndarray]:
    try:
        frame = first
        while frame is not None:
            yield cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)
            ok, frame = capture.read()
            frame = frame if ok else None
    finally:
        capture.release()


def _close_and_wake(waited_on) -> None:
    """Mark a source or a group closed and wake whoever waits on it."""
    with waited_on._changed:
        waited_on._closed = True
        waited_on._changed.notify_all()


def _wait_while_open(waited_on, ready) -> bool:
    """Wait, holding a source's or a group's lock, until ``ready()`` or it is closed (``StreamStalled`` after its
    stall timeout); whether it is still open."""
    timeout = waited_on.stall_s if np.isfinite(waited_on.stall_s) else None
    if not waited_on._changed.wait_for(lambda: waited_on._closed or ready(), timeout=timeout):
        raise StreamStalled(waited_on.name, waited_on.stall_s)
    return not waited_on._closed


class FrameSource:
    """``next()`` gives the oldest of the (at most ``keep``) newest frames not taken yet (waiting for one), None
    once the stream has ended, and raises ``StreamStalled`` when none has come for ``stall_s`` seconds. ``paced``
    plays the frames at ``fps`` (a file at its own rate); a camera or a stream paces itself. ``read`` counts the
    frames read, ``dropped`` those pushed out by newer ones before they were taken; a frame taken within
    ``keep`` frame periods of its arrival pushes none out. ``waits``: the reader waits for room instead (a file
    read as fast as it is processed: every frame taken, none dropped). ``stride``: only the frames whose number it
    divides are kept (set by whoever takes them, at any time); the others are read and counted as ``skipped``."""

    def __init__(self, frames: Iterator[np.ndarray], fps: float, name: str, paced: bool = False,
                 stall_s: float = 5.0, image_size: tuple[int, int] | None = None, keep: int = 2,
                 first_index: int = 0, waits: bool = False, stride: int = 1):
        if not fps > 0:
            raise InputError(f"{name}: the stream reports no frame rate; give it", ("fps",))
        self.fps, self.name, self.stall_s, self.image_size = float(fps), name, float(stall_s), image_size
        self.keep, self.first_index = max(1, int(keep)), int(first_index)
        self.read = self.dropped = self.skipped = 0
        self.stride = max(1, int(stride))
        self._frames, self._paced, self._waits = frames, paced, waits
        self._waiting: collections.deque = collections.deque(maxlen=self.keep)
        self._ended = self._closed = False
        self._failure: BaseException | None = None
        self._changed = threading.Condition()
        self.on_change: Callable[[], None] | None = None  # told of each frame and of the end (``SourceGroup``)
        self._reader = threading.Thread(target=self._read, name="frames", daemon=True)
        self._reader.start()

    @classmethod
    def open(cls, source: str | Path, fps: float | None = None, paced: bool | None = None,
             stall_s: float = 5.0, keep: int = 2, first_index: int = 0) -> FrameSource:
        """A video file (played at its own rate unless ``paced`` is False: then every frame as fast as it is
        taken), a camera device number or a stream URL; ``fps`` where the source does not say its rate. ``first_index``:
        the number of its first frame (a file is read from that frame on: a stream taken up again where it was left)."""
        source = str(source)
        is_file = Path(source).is_file()
        capture, first, reported = _opened(source, first_index if is_file else 0, None if is_file else stall_s + 1.0)
        return cls(_frames_of(capture, first), fps or reported, source, is_file if paced is None else paced, stall_s,
                   (first.shape[1], first.shape[0]), keep, first_index, waits=is_file and paced is False)

    @property
    def deadline_frames(self) -> int | None:
        """How many frame periods a frame may wait before a newer one pushes it out (None: it waits for its
        reader)."""
        return None if self._waits else self.keep

    def _read(self) -> None:
        start = time.monotonic()
        try:
            for index, image in enumerate(self._frames, start=self.first_index):
                if self._paced:
                    time.sleep(max(0.0, start + (index - self.first_index) / self.fps - time.monotonic()))
                if index % self.stride:
                    self.read += 1
                    self.skipped += 1
                    continue
                with self._changed:
                    if self._waits:
                        self._changed.wait_for(lambda: self._closed or len(self._waiting) < self._waiting.maxlen)
                    if self._closed:
                        return
                    self.dropped += len(self._waiting) == self._waiting.maxlen  # the oldest is pushed out
                    self._waiting.append(LiveFrame(index, image, time.monotonic()))
                    self.read += 1
                    self._changed.notify_all()
                self._tell()
        except Exception as err:  # a broken stream ends it; next() reports why
            self._failure = err
        finally:
            with self._changed:
                self._ended = True
                self._changed.notify_all()
            self._tell()

    def _tell(self) -> None:
        if (on_change := self.on_change) is not None:
            on_change()

    def ready(self) -> bool:
        """Whether ``next()`` would answer at once."""
        return bool(self._waiting) or self._ended or self._closed

    def oldest_arrival(self) -> float:
        """When the oldest frame waiting arrived (infinity when none waits)."""
        waiting = list(self._waiting)
        return waiting[0].arrived if waiting else np.inf

    def oldest_time_s(self) -> float:
        """The stream time of the oldest frame waiting (its number over the frame rate; infinity when none waits)."""
        waiting = list(self._waiting)
        return waiting[0].index / self.fps if waiting else np.inf

    def next(self) -> LiveFrame | None:
        """The newest frame not taken yet; None once the stream has ended or ``close`` was called."""
        with self._changed:
            if not _wait_while_open(self, lambda: self._waiting or self._ended):
                return None
            frame = self._waiting.popleft() if self._waiting else None
            self._changed.notify_all()  # a reader waiting for room
        if frame is None and self._failure is not None:
            raise InputError(f"{self.name}: the stream broke off: {self._failure}", ("source",))
        return frame

    def close(self) -> None:
        """Stop reading (the reader thread ends with its next frame)."""
        _close_and_wake(self)
        self._tell()

    def join(self, timeout_s: float) -> None:
        """Wait up to ``timeout_s`` for the reader thread to end (after ``close``)."""
        self._reader.join(timeout_s)


class SourceGroup:
    """Several sources (one per camera) taken as one: ``next()`` gives ``(view, frame)``, the frame that arrived
    first of those waiting in any source, waiting for one; None once every source has ended or the group was
    closed. ``StreamStalled`` when no source has given a frame for the longest of their stall timeouts. One
    source is a group of one.

    Where every source open waits for its reader (``deadline_frames`` None: files read as fast as they are
    processed), the frames are taken in the order of their stream times instead, on the first stream's clock
    (``offsets_s``: each stream's clock ahead of the first's, set by whoever joins the cameras' people), the first
    camera's first at a tie, waiting for every source's next frame: when the frames were read, which a busy
    machine's threads decide, changes nothing that is found in them."""

    def __init__(self, sources: list[FrameSource]):
        self.sources = list(sources)
        self.name = " + ".join(source.name for source in self.sources)
        self.stall_s = max(source.stall_s for source in self.sources)
        self.offsets_s = [0.0] * len(self.sources)
        self._changed = threading.Condition()
        self._open = set(range(len(self.sources)))
        self._closed = False
        for source in self.sources:
            source.on_change = self._notify

    def _notify(self) -> None:
        with self._changed:
            self._changed.notify_all()

    def _in_time_order(self) -> bool:
        return all(self.sources[v].deadline_frames is None for v in self._open)

    def _ready(self) -> bool:
        """Whether the next frame to take can be chosen: in time order, every open source's next frame is in (or
        its end); otherwise any source's."""
        ready = (self.sources[v].ready() for v in self._open)
        return all(ready) if self._in_time_order() else any(ready)

    def _first(self) -> int:
        """The source whose frame is taken next (all open sources ready, in time order; one at least otherwise)."""
        if self._in_time_order():  # an ended source (infinitely late: nothing waits) once it alone is left
            return min(self._open, key=lambda v: (self.sources[v].oldest_time_s() - self.offsets_s[v], v))
        return min((v for v in self._open if self.sources[v].ready()), key=lambda v: self.sources[v].oldest_arrival())

    def next(self) -> tuple[int, LiveFrame] | None:
        while True:
            with self._changed:
                if not _wait_while_open(self, self._ready):
                    return None
                view = self._first()
            frame = self.sources[view].next()
            if frame is not None:
                return view, frame
            self._open.discard(view)  # this one has ended (``next`` raised where it broke off)
            if not self._open:
                return None

    @property
    def read(self) -> int:
        return sum(source.read for source in self.sources)

    @property
    def dropped(self) -> int:
        return sum(source.dropped for source in self.sources)

    def close(self) -> None:
        _close_and_wake(self)
        for source in self.sources:
            source.close()

