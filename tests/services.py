"""Real servers for the tests that need one, each from Debian's packages, started on a free port on 127.0.0.1 and
stopped after its test (`make services` installs them): PostgreSQL, the Mosquitto MQTT broker, and an RTSP server
(rtsp-server-perl) fed by FFmpeg. A test whose server is missing is skipped, saying which package to install."""

from __future__ import annotations

import contextlib
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
import time
from pathlib import Path

import pytest

POSTGRES_BIN = Path("/usr/lib/postgresql")
MOSQUITTO = shutil.which("mosquitto") or ("/usr/sbin/mosquitto" if Path("/usr/sbin/mosquitto").exists() else None)
RTSP_SERVER = shutil.which("rtsp-server-perl")
FFMPEG = shutil.which("ffmpeg")


def _postgres_tools() -> Path | None:
    versions = sorted(POSTGRES_BIN.glob("*/bin/initdb")) if POSTGRES_BIN.is_dir() else []
    return versions[-1].parent if versions else None


needs_mosquitto = pytest.mark.skipif(MOSQUITTO is None, reason="Mosquitto not installed (Debian package mosquitto; "
                                                               "`make services` installs it)")
needs_rtsp = pytest.mark.skipif(RTSP_SERVER is None or FFMPEG is None,
                                reason="an RTSP server or FFmpeg not installed (Debian packages rtsp-server-perl, "
                                       "ffmpeg; `make services` installs them)")


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def wait_for_port(port: int, timeout_s: float = 20.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", port), timeout=0.5):
            return
        time.sleep(0.1)
    raise TimeoutError(f"nothing listens on 127.0.0.1:{port} after {timeout_s} s")


def _stop(process: subprocess.Popen) -> None:
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


@contextlib.contextmanager
def postgresql_server():
    """A PostgreSQL server of its own (a new cluster in a temporary folder, trusting local connections): yields
    its URL. As root, the server runs as the ``postgres`` user (it refuses root)."""
    tools = _postgres_tools()
    if tools is None:
        pytest.skip("PostgreSQL's server not installed (Debian package postgresql; `make services` installs it)")
    folder = Path(tempfile.mkdtemp(prefix="ray3d-pg-"))
    run_as: list[str] = []
    if os.geteuid() == 0:
        try:
            user = pwd.getpwnam("postgres")
        except KeyError:
            pytest.skip("running as root and no postgres user to run PostgreSQL's server as")
        os.chown(folder, user.pw_uid, user.pw_gid)
        run_as = ["runuser", "-u", "postgres", "--"]
    data, port = folder / "data", free_port()
    subprocess.run([*run_as, str(tools / "initdb"), "-D", str(data), "-A", "trust", "-U", "ray3d", "--no-sync"],
                   check=True, capture_output=True)
    server = subprocess.Popen([*run_as, str(tools / "postgres"), "-D", str(data), "-p", str(port), "-k", str(folder),
                               "-c", "listen_addresses=127.0.0.1", "-c", "fsync=off"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        wait_for_port(port)
        url = f"postgresql://ray3d@127.0.0.1:{port}/postgres"
        for _ in range(50):  # accepting connections a little after it listens
            if subprocess.run([str(tools / "pg_isready"), "-h", "127.0.0.1", "-p", str(port)],
                              capture_output=True).returncode == 0:
                break
            time.sleep(0.1)
        yield url
    finally:
        _stop(server)
        shutil.rmtree(folder, ignore_errors=True)


@contextlib.contextmanager
def mosquitto_broker():
    """A Mosquitto broker on a free port of 127.0.0.1 (anonymous clients allowed): yields the port."""
    if MOSQUITTO is None:
        pytest.skip("Mosquitto not installed (Debian package mosquitto; `make services` installs it)")
    folder = Path(tempfile.mkdtemp(prefix="ray3d-mqtt-"))
    port = free_port()
    (folder / "mosquitto.conf").write_text(f"listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n")
    broker = subprocess.Popen([MOSQUITTO, "-c", str(folder / "mosquitto.conf")], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
    try:
        wait_for_port(port)
        yield port
    finally:
        _stop(broker)
        shutil.rmtree(folder, ignore_errors=True)


class RtspStream:
    """An RTSP server (rtsp-server-perl) on free ports of 127.0.0.1, and FFmpeg publishing a test picture to it at
    ``fps`` (``start``/``stop`` the publisher: the stream goes down and comes back). ``url``: where clients read
    it (over UDP: set ``OPENCV_FFMPEG_CAPTURE_OPTIONS=rtsp_transport;udp``, as this server has no TCP transport)."""

    def __init__(self, size: tuple[int, int], fps: float = 10.0):
        self.size, self.fps = size, fps
        self.client_port, self.source_port = free_port(), free_port()
        self.url = f"rtsp://127.0.0.1:{self.client_port}/camera"
        self._server = subprocess.Popen([RTSP_SERVER, "--clientport", str(self.client_port), "--serverport",
                                         str(self.source_port), "--client_listen_address", "127.0.0.1",
                                         "--source_listen_address", "127.0.0.1", "--rtp_start_port",
                                         str(20000 + free_port() % 20000)],
                                        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        wait_for_port(self.source_port)
        self._publisher: subprocess.Popen | None = None

    def start(self) -> None:
        width, height = self.size
        self._publisher = subprocess.Popen(
            [FFMPEG, "-loglevel", "error", "-re", "-f", "lavfi", "-i",
             f"testsrc=size={width}x{height}:rate={self.fps:g}",
             "-c:v", "mpeg4", "-q:v", "8", "-g", "5", "-f", "rtsp",
             f"rtsp://127.0.0.1:{self.source_port}/camera"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)

    def stop(self) -> None:
        if self._publisher is not None:
            _stop(self._publisher)
            self._publisher = None

    def close(self) -> None:
        self.stop()
        _stop(self._server)
