#!/usr/bin/env bash
# A real camera stream that goes down and comes back: vtest.avi served over RTSP on 127.0.0.1 (rtsp-server-perl fed
# by FFmpeg, Debian packages), followed by `ray3d live` (its real detector) for 75 s while the publisher is stopped
# for 4 s and started again three times. Prints the run's summary, the lines it said and the store's gaps.
#   bash benchmarks/history/live_rtsp_restarts.sh ../shared/data/real-video OUT_DIR [RAY3D]
set -euo pipefail
data=$1; out=$2; ray3d=${3:-ray3d}
rm -rf "$out"; mkdir -p "$out"
client=18554; source=18555
rtsp-server-perl --clientport $client --serverport $source --client_listen_address 127.0.0.1 \
  --source_listen_address 127.0.0.1 --rtp_start_port 26000 >"$out/server.log" 2>&1 &
server=$!
publish() {
  ffmpeg -loglevel error -re -stream_loop -1 -i "$data/vtest.avi" -c:v mpeg4 -q:v 4 -g 10 -f rtsp \
    rtsp://127.0.0.1:$source/vtest >>"$out/publisher.log" 2>&1 &
  publisher=$!
}
publish; sleep 3
# This server has no TCP transport: OpenCV's FFmpeg reads it over UDP.
OPENCV_FFMPEG_CAPTURE_OPTIONS="rtsp_transport;udp" "$ray3d" live rtsp://127.0.0.1:$client/vtest \
  --camera "$data/vtest_camera.json" --site benchmarks/vtest_site.json --no-page --quiet --out "$out/live" \
  --until 75s --stall-timeout 2 --reconnect-max 4 2>"$out/live.log" &
live=$!
for k in 1 2 3; do
  sleep 15; kill $publisher; wait $publisher 2>/dev/null || true; sleep 4; publish
done
wait $live; echo "exit code $?"
kill $publisher $server 2>/dev/null || true
grep -v "INFO\|WARN\|^W0\|^I0\|mpeg4 @\|rtsp @\|cap_ffmpeg" "$out/live.log"
python3 - "$out/live/site.db" <<'PY'
import sqlite3, sys
connection = sqlite3.connect(sys.argv[1])
for camera, start, end, why in connection.execute("SELECT camera, from_at, to_at, why FROM gaps"):
    print(f"gap: {end - start:.1f} s ({why})")
starts = connection.execute("SELECT COUNT(*) FROM events WHERE kind = 'track started'").fetchone()[0]
print(f"tracks started: {starts}; events: {connection.execute('SELECT COUNT(*) FROM events').fetchone()[0]}")
spans = connection.execute("SELECT person, MIN(at), MAX(at) FROM events GROUP BY person").fetchall()
gaps = connection.execute("SELECT from_at, to_at FROM gaps").fetchall()
across = [p for p, first, last in spans for start, end in gaps if first < start and last > end]
print(f"people with events on both sides of a gap: {len(across)}")
PY
