"""A real headless browser for the tests of our pages (Chromium, `make browser` installs it): a page's console
errors, and screenshots as pixel arrays."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
needs_chromium = pytest.mark.skipif(CHROMIUM is None, reason="Chromium not installed (Debian packages chromium, "
                                                             "chromium-driver: `make browser` installs them)")
_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
          "--disable-component-update", "--no-first-run"]
_REPORT_ERRORS = ("<head><script>window.__errors=[];window.onerror=function(m){window.__errors.push(String(m))};"
                  "</script>", "<script>setTimeout(function(){var d=document.createElement('pre');d.id='errors';"
                  "d.textContent=JSON.stringify(window.__errors);document.body.appendChild(d);},300);</script></body>")


def _run(arguments: list[str], profile: Path) -> str:
    return subprocess.run([CHROMIUM, *_FLAGS, f"--user-data-dir={profile}", *arguments], capture_output=True,
                          text=True, timeout=120).stdout


def console_errors(page: Path, fragment: str = "") -> str:
    """The page's console errors as the JSON list its DOM reports ("[]" when none), read from a copy of it made to
    report them (beside it)."""
    probe = page.with_name("probe-" + page.name)
    probe.write_text(page.read_text().replace("<head>", _REPORT_ERRORS[0], 1).replace("</body>", _REPORT_ERRORS[1]))
    dom = _run(["--virtual-time-budget=2000", "--dump-dom", probe.as_uri() + fragment], page.parent / "profile")
    return dom.split('<pre id="errors">', 1)[1].split("</pre>", 1)[0] if '<pre id="errors">' in dom else dom[-500:]


def screenshot(url: str, path: Path, size: str = "1000,800", live: bool = False, wait_s: float = 3.0) -> np.ndarray:
    """(H, W, 3) the page at ``url`` as Chromium draws it; ``live``: after ``wait_s`` of real time (a page fed by a
    stream: time for Chromium to start, connect and draw on a busy machine), else after its scripts settle."""
    timing = f"--timeout={int(1000 * wait_s)}" if live else "--virtual-time-budget=2000"
    _run([timing, f"--window-size={size}", f"--screenshot={path}", url], path.with_name(path.stem + "-profile"))
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB")).astype(int)
