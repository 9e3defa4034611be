"""A network stream (or a camera device) that is opened again whenever it stalls, breaks off or ends
(``ReconnectingSource``): what ``ray3d live`` follows for months, the gaps it leaves recorded."""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Callable

import numpy as np

from ray3d.errors import InputError
from ray3d.live.source import FrameSource, LiveFrame
from ray3d.store.database import without_passwords


class ReconnectingSource:
    """A network stream (or a camera device) that is opened again whenever it stalls (no frame for ``stall_s``),
    breaks off or ends, with a backoff from ``backoff_s`` doubling up to ``max_backoff_s`` between tries, on a
    thread of its own: while it is down, a ``SourceGroup``'s other sources go on, and this one is simply not ready
    (it never stalls the group: ``stall_s`` for the group is infinite). Frame numbers go on with the time that
    passed, so that the stream's clock does; the first frame after each reopening carries the ``gap``.
    ``report`` is told one line when the stream goes down and one when it is back. It ends only when closed."""

    def __init__(self, location: str, fps: float | None = None, stall_s: float = 5.0, keep: int = 2,
                 backoff_s: float = 1.0, max_backoff_s: float = 30.0,
                 report: Callable[[str], None] = lambda line: None):
        # Said without the URL's password (its lines go to a service's journal).
        self.location, self.name, self.keep, self.report = str(location), without_passwords(location), keep, report
        self.stream_stall_s, self.backoff_s, self.max_backoff_s = float(stall_s), backoff_s, max_backoff_s
        self.stall_s = np.inf
        self.on_change: Callable[[], None] | None = None
        self._changed = threading.Condition()
        self._closed = False
        self._done_read = self._done_dropped = 0
        self._current = FrameSource.open(self.location, fps, paced=False, stall_s=self.stream_stall_s, keep=keep)
        self.fps, self.image_size = self._current.fps, self._current.image_size
        self._current.on_change = self._tell
        self._last_index, self._last_wall = -1, time.time()
        self._down_after: int | None = None  # reopened, no frame taken yet: the last frame's number before
        self._opened_at = time.time()  # the stall clock starts again with each opening
        self._let_go: list[FrameSource] = []  # streams closed while down, their readers still in a read
        self._keeper = threading.Thread(target=self._keep_open, name="reconnect", daemon=True)
        self._keeper.start()

    deadline_frames = property(lambda self: self.keep)
    read = property(lambda self: self._done_read + (self._current.read if self._current else 0))
    dropped = property(lambda self: self._done_dropped + (self._current.dropped if self._current else 0))

    def _tell(self) -> None:
        with self._changed:
            self._changed.notify_all()
        if (on_change := self.on_change) is not None:
            on_change()

    def _is_down(self, current: FrameSource) -> str | None:
        """Why the stream is down (None while it is not)."""
        if current._ended and not current._waiting:
            return f"it broke off ({current._failure})" if current._failure else "it ended"
        if time.time() - max(self._last_wall, self._opened_at) > self.stream_stall_s and not current._waiting:
            return f"no frame for {self.stream_stall_s:g} s"
        return None

    def _keep_open(self) -> None:
        while True:
            with self._changed:
                self._changed.wait_for(lambda: self._closed or self._is_down(self._current) is not None,
                                       timeout=0.2)
                if self._closed:
                    return
                why = self._is_down(self._current)
                if why is None:
                    continue
                down, self._current = self._current, None
            down.close()
            self._let_go.append(down)
            self._done_read, self._done_dropped = self._done_read + down.read, self._done_dropped + down.dropped
            self.report(f"{self.name}: the stream is down ({why}); opening it again (every "
                        f"{self.backoff_s:g}-{self.max_backoff_s:g} s); nobody is followed across the gap")
            wait, tries = self.backoff_s, 0
            while not self._closed:
                tries += 1
                try:
                    first = self._last_index + 1 + int(round((time.time() - self._last_wall) * self.fps))
                    opened = FrameSource.open(self.location, self.fps, paced=False, stall_s=self.stream_stall_s,
                                              keep=self.keep, first_index=first)
                except InputError:
                    with self._changed:
                        self._changed.wait_for(lambda: self._closed, timeout=wait)
                    wait = min(2 * wait, self.max_backoff_s)
                    continue
                with self._changed:
                    if self._closed:
                        opened.close()
                        return
                    self._down_after = self._last_index
                    self._opened_at = time.time()
                    self._current = opened
                    opened.on_change = self._tell
                self.report(f"{self.name}: the stream is back after {time.time() - self._last_wall:.1f} s "
                            f"({tries} tries); the gap is recorded")
                self._tell()
                break

    def ready(self) -> bool:
        current = self._current
        return self._closed or (current is not None and bool(current._waiting))

    def oldest_arrival(self) -> float:
        current = self._current
        return current.oldest_arrival() if current is not None else np.inf

    def next(self) -> LiveFrame | None:
        """The next frame (waiting while the stream is down); None once closed."""
        while True:
            with self._changed:
                self._changed.wait_for(lambda: self._closed or (self._current is not None and self._current._waiting))
                if self._closed:
                    return None
                current = self._current
            frame = current.next()
            if frame is None:
                continue
            with self._changed:
                if self._down_after is not None:
                    frame = dataclasses.replace(frame, gap=(self._down_after, frame.index))
                    self._down_after = None
                self._last_index, self._last_wall = frame.index, time.time()
            return frame

    def close(self) -> None:
        """Stop reading; returns once every reader has ended (each within the stream's read timeout)."""
        with self._changed:
            self._closed = True
            current = self._current
            self._changed.notify_all()
        if current is not None:
            current.close()
        self._tell()
        self._keeper.join(self.stream_stall_s + 15.0)
        for source in [*self._let_go, *([current] if current is not None else [])]:
            source.join(self.stream_stall_s + 2.0)
