"""Quiet logs (issue 68): a progress bar is drawn only when stderr is a terminal, so a service's log (stderr a
file) gets no carriage-return updates; native libraries' INFO lines (LiteRT's "Created TensorFlow Lite XNNPACK
delegate") are dropped and every other line written to stderr meanwhile is kept."""

from __future__ import annotations

import fcntl
import os
import pty
import struct
import subprocess
import sys
import termios
import textwrap
import threading

import numpy as np
import pytest

from ray3d import cameras
from ray3d.demo import demo_clip
from ray3d.io.world import LiftResult, World, write_world

BAR = "from ray3d.console import progress_bar\nfor _ in progress_bar(range(300), desc='counting', mininterval=0): pass"


def _run(code: str, stderr) -> int:
    done = subprocess.run([sys.executable, "-c", code], stderr=stderr, stdout=subprocess.DEVNULL, timeout=300)
    return done.returncode


def test_a_progress_bar_writes_nothing_into_a_file_and_draws_on_a_terminal(tmp_path):
    log = tmp_path / "log"
    with log.open("wb") as handle:
        assert _run(BAR, handle) == 0
    assert log.read_bytes() == b""
    master, slave = pty.openpty()  # the same bar with stderr a terminal (24 x 80) is drawn
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))
    drawn = bytearray()
    reader = threading.Thread(target=lambda: _drain(master, drawn), daemon=True)
    reader.start()
    try:
        assert _run(BAR, slave) == 0
    finally:
        os.close(slave)
        reader.join(timeout=30)
        os.close(master)
    assert b"\r" in drawn and b"counting" in drawn


def _drain(fd: int, into: bytearray) -> None:
    while True:
        try:
            chunk = os.read(fd, 4096)
        except OSError:  # the terminal's other end closed
            return
        if not chunk:
            return
        into += chunk


def test_a_command_with_a_progress_bar_writes_no_carriage_return_into_its_log(tmp_path):
    """``ray3d viz --animation`` draws a bar over the frames it renders: with stderr a file, none of it."""
    joints = demo_clip()[:40]
    world = write_world(tmp_path / "w.json", World({"7": LiftResult(joints, np.zeros((40, 17), bool), 30.0,
                                                                    np.arange(40))},
                                                   cameras.h36m("S9", "54138969"), "test"))
    log = tmp_path / "log"
    with log.open("wb") as handle:
        done = subprocess.run([sys.executable, "-c", "import sys; from ray3d.cli import main; sys.exit(main())",
                               "viz", str(world), "--animation", str(tmp_path / "a.gif"), "--stride", "2"],
                              stdout=subprocess.DEVNULL, stderr=handle, timeout=600)
    assert done.returncode == 0 and (tmp_path / "a.gif").is_file()
    assert b"\r" not in log.read_bytes() and b"rendering" not in log.read_bytes()


def test_native_chatter_is_dropped_and_everything_else_kept(tmp_path):
    code = textwrap.dedent("""
        import os, sys
        from ray3d.console import native_chatter_dropped
        print("before", file=sys.stderr)
        with native_chatter_dropped():
            os.write(2, b"INFO: Created TensorFlow Lite XNNPACK delegate for CPU.\\n")
            os.write(2, b"WARNING: All log messages before absl::InitializeLog() is called are written to STDERR\\n")
            os.write(2, b"E0000 00:00:1.0 1 graph.cc:1] a real error\\n")
            print("a line of ours", file=sys.stderr)
        print("after", file=sys.stderr)
    """)
    log = tmp_path / "log"
    with log.open("wb") as handle:
        assert _run(code, handle) == 0
    assert log.read_text().splitlines() == ["before", "E0000 00:00:1.0 1 graph.cc:1] a real error", "a line of ours",
                                            "after"]


def test_the_video_detectors_start_without_an_info_line(tmp_path):
    pytest.importorskip("ai_edge_litert", reason="the video extra is not installed: pip install 'ray3d[video]'")
    code = textwrap.dedent("""
        import numpy as np
        from ray3d.video.movenet import MoveNetPeople
        from ray3d.video.landmarks import BlazePoseLandmarks
        frame = np.zeros((240, 320, 3), np.uint8)
        MoveNetPeople(threads=1)(frame)
        BlazePoseLandmarks(threads=1)(frame, np.array([[160.0, 120.0, 100.0, 0.0]]))
    """)
    log = tmp_path / "log"
    with log.open("wb") as handle:
        assert _run(code, handle) == 0
    assert "INFO" not in log.read_text(), log.read_text()
