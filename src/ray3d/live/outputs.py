"""Where live events go besides the page and their JSON-lines file (``site.files.EventLines``): a webhook
(HTTP POST of each event as JSON, retried, from a bounded queue on a thread of its own, so a receiver that refuses
or hangs never slows the stream: what it cannot take is counted)."""

from __future__ import annotations

import json
import queue
import sys
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Callable

from ray3d.console import said_once


class Webhook:
    """POST each event (JSON) to ``url``: ``attempts`` tries ``timeout_s`` each, waiting ``backoff_s`` doubling in
    between; at most ``queue_size`` events wait (a new one beyond that pushes out the oldest). ``report`` is told,
    once, in one line, the first time the receiver cannot be reached. ``delivered``, ``failed`` (given up after
    every attempt) and ``dropped`` (pushed out of the queue, or still queued at ``close``) count the events."""

    def __init__(self, url: str, queue_size: int = 1000, attempts: int = 3, timeout_s: float = 2.0,
                 backoff_s: float = 0.25, report: Callable[[str], None] = lambda line: print(line, file=sys.stderr),
                 token: str | None = None):
        self.url, self.attempts, self.timeout_s, self.backoff_s = url, attempts, timeout_s, backoff_s
        self.report_trouble = said_once(report)
        self.headers = {"Content-Type": "application/json", **({"Authorization": f"Bearer {token}"} if token else {})}
        self.delivered = self.failed = self.dropped = 0
        self._queue: queue.Queue = queue.Queue(maxsize=queue_size)
        self._sending = False
        self._counting = threading.Lock()
        self._stop = threading.Event()
        self._sender = threading.Thread(target=self._send_all, name="webhook", daemon=True)
        self._sender.start()

    def post(self, events: list[dict]) -> None:
        for event in events:
            while True:
                try:
                    self._queue.put_nowait(event)
                    break
                except queue.Full:
                    self._drop_oldest()

    def _drop_oldest(self) -> bool:
        """Drop the oldest waiting event (counted); False when none was waiting."""
        try:
            self._queue.get_nowait()
        except queue.Empty:
            return False
        self.dropped += 1
        return True

    def _send_all(self) -> None:
        while not (self._stop.is_set() and self._queue.empty()):
            try:
                event = self._queue.get(timeout=0.1)
            except queue.Empty:
                continue
            with self._counting:
                self._sending = True
            outcome = self._send(event)
            with self._counting:
                if self._sending:  # not yet given up by ``close``
                    self._sending = False
                    if outcome:
                        self.delivered += 1
                    else:
                        self.failed += 1

    def _send(self, event: dict) -> bool:
        """Whether ``event`` was delivered."""
        body = json.dumps(event).encode()
        for attempt in range(self.attempts):
            try:
                request = urllib.request.Request(self.url, data=body, headers=self.headers, method="POST")
                with urllib.request.urlopen(request, timeout=self.timeout_s) as response:
                    response.read()
                return True
            except (urllib.error.URLError, OSError, ValueError) as err:
                why = getattr(err, "reason", None) or err
                if self._stop.is_set():
                    break
                if attempt + 1 < self.attempts:
                    time.sleep(self.backoff_s * 2 ** attempt)
        self.report_trouble(f"webhook {self.url}: not delivered after {self.attempts} attempts ({why}); events stay "
                            "in events.jsonl")
        return False

    def close(self, wait_s: float = 3.0) -> None:
        """Send what is queued for up to ``wait_s`` seconds, then count the rest as dropped."""
        deadline = time.monotonic() + wait_s
        while not self._queue.empty() and time.monotonic() < deadline:
            time.sleep(0.02)
        self._stop.set()
        self._sender.join(timeout=max(0.0, deadline - time.monotonic()) + self.timeout_s)
        with self._counting:
            if self._sending:  # one still on its way to a receiver that hangs: given up
                self._sending = False
                self.dropped += 1
        while self._drop_oldest():
            pass
