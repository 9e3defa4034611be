"""What ray3d writes to the console besides its own lines, kept fit for a log (issue 68): progress bars only when
stderr is a terminal (a service's log, ``2> log``, gets no carriage-return updates), through the one
``progress_bar`` every bar is made by; and the INFO lines native libraries print as they start (LiteRT's "INFO:
Created TensorFlow Lite XNNPACK delegate for CPU.", MediaPipe's absl preamble), which no environment variable of
theirs silences, dropped by ``native_chatter_dropped`` around the calls that print them."""

from __future__ import annotations

import contextlib
import os
import re
import sys
import tempfile
import threading
from collections.abc import Callable
from typing import Any, Iterable

from tqdm import tqdm


def stderr_is_terminal() -> bool:
    """Whether stderr is a terminal (not a file, a pipe, a journal, a test's capture)."""
    try:
        return bool(sys.stderr.isatty())
    except (AttributeError, ValueError):  # replaced by an object without isatty, or closed
        return False


def showing_progress(wanted: bool = True) -> bool:
    """Whether a progress bar is drawn: when ``wanted`` and stderr is a terminal. The ``progress`` argument to pass
    a library function that draws its own bar."""
    return bool(wanted) and stderr_is_terminal()


def progress_bar(iterable: Iterable | None = None, *, shown: bool = True, **options: Any) -> tqdm:
    """A tqdm progress bar (``options`` as tqdm's: ``total``, ``desc``, ``unit``, ``leave``, ...) drawn only when
    ``shown`` and stderr is a terminal; otherwise a bar that writes nothing but still iterates and counts."""
    return tqdm(iterable, disable=not showing_progress(shown), **options)


# Lines native libraries print to stderr as they start, of no use to a user: TensorFlow Lite's minimal logger at
# INFO, absl's notice that logging is not initialised, absl's INFO lines (I0000 00:00:...) and MediaPipe's warning
# that its graph's models have no feedback tensors (W0000 ... inference_feedback_manager.cc).
CHATTER = re.compile(rb"^(INFO: .*"
                     rb"|WARNING: All log messages before absl::InitializeLog\(\) is called are written to STDERR"
                     rb"|I\d{4} [\d:. ]+\d+ [\w.]+:\d+\] .*"
                     rb"|W\d{4} [\d:. ]+\d+ inference_feedback_manager\.cc:\d+\] .*)$")
_LOCK = threading.RLock()


@contextlib.contextmanager
def native_chatter_dropped():
    """While the block runs, whatever is written to the stderr file descriptor (by native code, or by any thread)
    is held; after it, written back but for ``CHATTER`` lines. Nothing else is lost, only delayed by the block (a
    native library's start: milliseconds). Where stderr has no descriptor, the block just runs."""
    with _LOCK:
        try:
            sys.stderr.flush()
            saved = os.dup(2)
        except (AttributeError, OSError, ValueError):
            yield
            return
        with tempfile.TemporaryFile() as held:
            os.dup2(held.fileno(), 2)
            try:
                yield
            finally:
                with contextlib.suppress(Exception):
                    sys.stderr.flush()
                os.dup2(saved, 2)
                os.close(saved)
                held.seek(0)
                lines = held.read().splitlines(keepends=True)
                text = b"".join(line for line in lines if not CHATTER.match(line.rstrip(b"\r\n")))
                while text:
                    text = text[os.write(2, text):]


def said_once(report: Callable[[str], None]) -> Callable[[str], None]:
    """``report``, saying only the first line it is given: a trouble that comes back with every event (a receiver
    that cannot be reached) is one line in the log, not one an event."""
    said = threading.Event()

    def say(line: str) -> None:
        if not said.is_set():
            said.set()
            report(line)

    return say
