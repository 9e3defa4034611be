"""A self-contained, offline HTML viewer of 3D sequences: orbit (drag), zoom (wheel), play/pause, a frame
slider with the time, several people or methods at once (each in its own colour, labelled, over a shared ground
grid with axes and a metre scale), a floor plan with everybody's path, a "follow" choice that keeps one person
in the middle, and four views: orbit, top, side and through the camera itself. The camera stays in view: where
it lies outside the picture, a marker on the edge points to it. ``viewer.html#view=top`` (or side, camera)
opens in that view; ``#frame=N`` opens paused at frame N and ``#follow=TRACK`` follows one person (joined with &).

A sequence is either world joints (T, 17, 3) from frame 0 or a ``LiftResult`` (a track of a world file: it
starts at its own frame, frames it filled in rather than detected are drawn thin and grey, and where it has a
position uncertainty an ellipse on the floor under the pelvis shows one standard deviation: along the camera's
ray, as seen from above, and across it)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ray3d.io.atomic import write_text
from ray3d.io.world import LiftResult
from ray3d.skeleton import H36M17
from ray3d.viz.animation import PALETTE, as_track, frustum_lines

_TEMPLATE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>__TITLE__</title>
<style>
 body { font-family: sans-serif; margin: 0; background: #fafafa; }
 #bar { padding: 8px; display: flex; gap: 12px; align-items: center; flex-wrap: wrap; }
 #view { display: block; width: 100%; background: #ffffff; border-top: 1px solid #ddd; cursor: grab; }
 .key { display: inline-block; width: 14px; height: 4px; margin-right: 4px; vertical-align: middle; }
</style></head>
<body>
<div id="bar">
 <button id="play">pause</button>
 <input id="slider" type="range" min="0" value="0" style="width: 30%">
 <span id="label"></span>
 <label>view <select id="viewmode"><option>orbit</option><option>top</option>\
<option>side</option><option>camera</option></select></label>
 <label>follow <select id="follow"><option value="">everybody</option></select></label>
 <span id="legend"></span>
 <span style="color: #777">drag to orbit, wheel to zoom; metres, z up; grey: filled in, not detected; \
disc on the floor: 1 sd of the position</span>
</div>
<canvas id="view"></canvas>
<script>
const DATA = __DATA__;
const canvas = document.getElementById("view"), ctx = canvas.getContext("2d");
const slider = document.getElementById("slider"), label = document.getElementById("label");
const follow = document.getElementById("follow"), viewmode = document.getElementById("viewmode");
const names = Object.keys(DATA.sequences), first = DATA.first, frames = DATA.last - DATA.first + 1;
slider.max = frames - 1;
let frame = 0, playing = true, yaw = -0.6, elevation = 0.35, zoom = 1.0, centre = DATA.centre.slice();
names.forEach(n => { const o = document.createElement("option"); o.value = n; o.textContent = n; \
follow.appendChild(o); });
document.getElementById("legend").innerHTML = names.map((n, i) =>
  `<span class="key" style="background:${DATA.colours[i]}"></span>${n}`).join(" &nbsp; ");
function resize() {  // the whole window below the bar (which grows with the legend)
  canvas.width = Math.max(320, window.innerWidth);
  canvas.height = Math.max(240, window.innerHeight - document.getElementById("bar").offsetHeight - 6); draw(); }
function pose(seq, absolute) { const row = absolute - seq.start; \
return row >= 0 && row < seq.joints.length ? row : -1; }
function metre() { return zoom * canvas.height / (2.2 * DATA.extent); }  // pixels per metre (not the camera view)
function imageFit() {  // the camera's image inside the canvas: scale and offset
  const c = DATA.camera, s = zoom * Math.min(canvas.width / c.width, canvas.height / c.height);
  return [s, (canvas.width - s * c.width) / 2, (canvas.height - s * c.height) / 2];
}
function project(p) {  // [x, y, depth] on the canvas, or null behind the camera
  if (viewmode.value === "camera") {
    const c = DATA.camera, R = c.R, q = [0, 1, 2].map(i => R[i][0] * p[0] + R[i][1] * p[1] + R[i][2] * p[2] + c.t[i]);
    if (q[2] < 0.05) return null;
    const [s, ox, oy] = imageFit();
    return [ox + s * (c.fx * q[0] / q[2] + c.cx), oy + s * (c.fy * q[1] / q[2] + c.cy), q[2]];
  }
  const x = p[0] - centre[0], y = p[1] - centre[1], z = p[2];
  const cx = Math.cos(yaw) * x - Math.sin(yaw) * y, cy = Math.sin(yaw) * x + Math.cos(yaw) * y;
  // Seen from the -y side, raised by the elevation: +x to the right, +y away (from above: a map, y up).
  const depth = Math.cos(elevation) * cy - Math.sin(elevation) * z;
  const up = Math.sin(elevation) * cy + Math.cos(elevation) * z;
  const anchor = 0.7 - 0.2 * Math.max(0, elevation) / (Math.PI / 2);  // the ground in the middle from above
  return [canvas.width / 2 + metre() * cx, canvas.height * anchor - metre() * up, depth];
}
function line(a, b, colour, width) {
  const p = project(a), q = project(b);
  if (!p || !q) return;
  ctx.strokeStyle = colour; ctx.lineWidth = width;
  ctx.beginPath(); ctx.moveTo(p[0], p[1]); ctx.lineTo(q[0], q[1]); ctx.stroke();
}
function cameraMarker() {  // the camera on the canvas, or an arrow on the edge pointing to it
  if (!DATA.camera || viewmode.value === "camera") return;
  const p = project(DATA.camera.centre), w = canvas.width, h = canvas.height, m = 14;
  ctx.fillStyle = "#000"; ctx.font = "12px sans-serif";
  if (p[0] > m && p[0] < w - m && p[1] > m && p[1] < h - m) { ctx.fillRect(p[0] - 4, p[1] - 4, 8, 8);
    ctx.fillText("camera", p[0] + 7, p[1] + 4); return; }
  const dx = p[0] - w / 2, dy = p[1] - h / 2, k = Math.min((w / 2 - m) / Math.abs(dx || 1e-9), \
(h / 2 - m) / Math.abs(dy || 1e-9));
  const e = [w / 2 + dx * k, h / 2 + dy * k], a = Math.atan2(dy, dx);
  ctx.beginPath(); ctx.moveTo(e[0] + 10 * Math.cos(a), e[1] + 10 * Math.sin(a));
  ctx.lineTo(e[0] + 8 * Math.cos(a + 2.5), e[1] + 8 * Math.sin(a + 2.5));
  ctx.lineTo(e[0] + 8 * Math.cos(a - 2.5), e[1] + 8 * Math.sin(a - 2.5)); ctx.fill();
  const text = "camera " + Math.hypot(DATA.camera.centre[0] - centre[0], \
DATA.camera.centre[1] - centre[1]).toFixed(0) + " m";
  ctx.fillText(text, Math.min(w - 90, Math.max(4, e[0] - 30 * Math.cos(a) - 20)), \
Math.min(h - 6, Math.max(14, e[1] - 22 * Math.sin(a))));
}
function scaleBar() {
  if (viewmode.value === "camera") return;
  const metres = [0.5, 1, 2, 5, 10, 20, 50, 100].find(m => m * metre() >= 60) || 100;  // a round length, 60 px or more
  const s = metres * metre(), x0 = 14, y0 = canvas.height - 14;
  ctx.strokeStyle = "#333"; ctx.lineWidth = 2; ctx.beginPath();
  ctx.moveTo(x0, y0 - 5); ctx.lineTo(x0, y0); ctx.lineTo(x0 + s, y0); ctx.lineTo(x0 + s, y0 - 5); ctx.stroke();
  ctx.fillStyle = "#333"; ctx.font = "12px sans-serif"; ctx.fillText(`${metres} m`, x0 + s / 2 - 12, y0 - 7);
}
function floorPlan(absolute) {
  const size = Math.min(220, canvas.width / 4), x0 = canvas.width - size - 10, y0 = 10, b = DATA.bounds;
  const span = Math.max(b[2] - b[0], b[3] - b[1], 1e-3), s = (size - 20) / span;
  const at = p => [x0 + 10 + (p[0] - b[0]) * s, y0 + size - 10 - (p[1] - b[1]) * s];
  ctx.fillStyle = "rgba(255,255,255,0.92)"; ctx.fillRect(x0, y0, size, size);
  ctx.strokeStyle = "#bbb"; ctx.lineWidth = 1; ctx.strokeRect(x0, y0, size, size);
  ctx.fillStyle = "#555"; ctx.font = "11px sans-serif";
  ctx.textAlign = "right"; ctx.fillText(`floor plan, ${span.toFixed(1)} m across`, x0 + size - 6, y0 + size - 5);
  ctx.textAlign = "left";
  names.forEach((name, i) => {
    const seq = DATA.sequences[name];
    ctx.strokeStyle = DATA.colours[i]; ctx.globalAlpha = 0.45; ctx.beginPath();
    seq.joints.forEach((j, t) => { const q = at(j[0]); t ? ctx.lineTo(q[0], q[1]) : ctx.moveTo(q[0], q[1]); });
    ctx.stroke(); ctx.globalAlpha = 1;
    const row = pose(seq, absolute);
    if (row >= 0) { const q = at(seq.joints[row][0]); ctx.fillStyle = DATA.colours[i];
      ctx.beginPath(); ctx.arc(q[0], q[1], 3.5, 0, 7); ctx.fill(); ctx.fillText(name, q[0] + 5, q[1] - 4); }
  });
  if (DATA.camera_lines.length) { const q = at(DATA.camera_lines[0][0]); ctx.fillStyle = "#000";
    ctx.fillRect(q[0] - 3, q[1] - 3, 6, 6); ctx.fillText("camera", q[0] + 5, q[1] + 4); }
  DATA.more_cameras.forEach(c => { const q = at(c.centre), right = q[0] > x0 + size / 2; ctx.fillStyle = "#000";
    ctx.fillRect(q[0] - 3, q[1] - 3, 6, 6); ctx.textAlign = right ? "right" : "left";
    ctx.fillText(c.name, q[0] + (right ? -5 : 5), q[1] + 4); ctx.textAlign = "left"; });
}
function uncertainty(pelvis, sd, colour) {  // [along the ray from above, across, ray direction x, y] on the floor
  const [a, b, ux, uy] = sd, points = [];
  for (let k = 0; k < 24; k++) { const t = k * Math.PI / 12, \
q = project([pelvis[0] + a * Math.cos(t) * ux - b * Math.sin(t) * uy,
    pelvis[1] + a * Math.cos(t) * uy + b * Math.sin(t) * ux, 0]); if (!q) return; points.push(q); }
  ctx.beginPath(); points.forEach((q, k) => k ? ctx.lineTo(q[0], q[1]) : ctx.moveTo(q[0], q[1])); ctx.closePath();
  ctx.globalAlpha = 0.2; ctx.fillStyle = colour; ctx.fill(); ctx.globalAlpha = 0.8; ctx.strokeStyle = colour;
  ctx.lineWidth = 1; ctx.stroke(); ctx.globalAlpha = 1;
}
function draw() {
  const absolute = first + frame;
  if (follow.value) { const seq = DATA.sequences[follow.value], row = pose(seq, absolute);
    if (row >= 0) centre = [seq.joints[row][0][0], seq.joints[row][0][1]]; }
  ctx.fillStyle = "#ffffff"; ctx.fillRect(0, 0, canvas.width, canvas.height);
  const through = viewmode.value === "camera";
  ctx.save();
  if (through) { const [s, ox, oy] = imageFit(); ctx.fillStyle = "#f4f4f4";
    ctx.fillRect(ox, oy, s * DATA.camera.width, s * DATA.camera.height); ctx.strokeStyle = "#999";
    ctx.strokeRect(ox, oy, s * DATA.camera.width, s * DATA.camera.height);
    ctx.beginPath(); ctx.rect(ox, oy, s * DATA.camera.width, s * DATA.camera.height); ctx.clip(); }
  const g = DATA.extent, c = [Math.round(centre[0] * 2) / 2, Math.round(centre[1] * 2) / 2];
  for (let k = -g; k <= g + 1e-9; k += 0.5)  // in short pieces: through the camera a piece may lie behind it
    for (let m = -g; m < g - 1e-9; m += 0.5) {
      line([c[0] + k, c[1] + m, 0], [c[0] + k, c[1] + m + 0.5, 0], "#e3e3e3", 1);
      line([c[0] + m, c[1] + k, 0], [c[0] + m + 0.5, c[1] + k, 0], "#e3e3e3", 1);
    }
  line([c[0], c[1], 0], [c[0] + 1, c[1], 0], "#d62f2f", 2); line([c[0], c[1], 0], [c[0], c[1] + 1, 0], "#2a9d3c", 2);
  line([c[0], c[1], 0], [c[0], c[1], 1], "#1f5fd6", 2);
  ctx.fillStyle = "#555"; ctx.font = "12px sans-serif";
  [["x, 1 m", [c[0] + 1.05, c[1], 0]], ["y", [c[0], c[1] + 1.05, 0]], ["z", [c[0], c[1], 1.05]]].forEach(([t, p]) => {
    const q = project(p); if (q) ctx.fillText(t, q[0], q[1]); });
  if (!through) DATA.camera_lines.concat(...DATA.more_cameras.map(c => c.lines)).forEach(s => \
line(s[0], s[1], "#999999", 1));
  names.forEach((name, i) => {
    const seq = DATA.sequences[name], row = pose(seq, absolute);
    if (row < 0) return;
    for (let t = 1; t <= row; t++)
      line([seq.joints[t - 1][0][0], seq.joints[t - 1][0][1], 0], [seq.joints[t][0][0], seq.joints[t][0][1], 0], \
DATA.colours[i], 1);
    const p = seq.joints[row], filled = seq.filled[row], colour = filled ? "#aaaaaa" : DATA.colours[i];
    if (seq.sd) uncertainty(p[0], seq.sd[row], DATA.colours[i]);
    DATA.parents.forEach((q, j) => { if (q >= 0) line(p[j], p[q], colour, filled ? 1 : (DATA.sides[j] ? 3 : 2)); });
    const head = project(p[10]); ctx.fillStyle = colour; ctx.font = "13px sans-serif";
    if (head) ctx.fillText(name, head[0] + 6, head[1] - 6);
  });
  ctx.restore(); scaleBar(); floorPlan(absolute); cameraMarker();
  label.textContent = `frame ${absolute} (${frame + 1} / ${frames}), ${(absolute / DATA.fps).toFixed(2)} s`;
  slider.value = frame;
}
document.getElementById("play").onclick = e => { playing = !playing; \
e.target.textContent = playing ? "pause" : "play"; };
slider.oninput = () => { frame = +slider.value; draw(); };
// Following one person zooms in on them (about 8 m across); everybody again shows the whole scene.
follow.onchange = () => { if (!follow.value) centre = DATA.centre.slice();
  zoom = follow.value ? Math.max(1, DATA.extent / 4) : 1.0; draw(); };
const PRESETS = {orbit: [-0.6, 0.35], top: [0.0, Math.PI / 2], side: [0.0, 0.0], camera: [yaw, elevation]};
function setView(mode) { viewmode.value = mode; [yaw, elevation] = PRESETS[mode]; zoom = 1.0; draw(); }
viewmode.onchange = () => setView(viewmode.value);
if (!DATA.camera) viewmode.querySelector("option:last-child").disabled = true;
let drag = null;
canvas.onmousedown = e => { drag = [e.clientX, e.clientY, yaw, elevation]; };
window.onmouseup = () => { drag = null; };
window.onmousemove = e => { if (!drag) return;
  yaw = drag[2] - (e.clientX - drag[0]) * 0.01;
  elevation = Math.max(-0.2, Math.min(Math.PI / 2, drag[3] + (e.clientY - drag[1]) * 0.01));
  if (viewmode.value === "camera") viewmode.value = "orbit";
  draw(); };
canvas.onwheel = e => { e.preventDefault(); zoom *= e.deltaY < 0 ? 1.1 : 0.9; draw(); };
window.onresize = resize;
setInterval(() => { if (playing) { frame = (frame + 1) % frames; draw(); } }, 1000 / DATA.fps);
const asked = (location.hash.match(/view=([a-z]+)/) || [])[1];
if (Object.keys(PRESETS).includes(asked) && (asked !== "camera" || DATA.camera)) viewmode.value = asked;
[yaw, elevation] = viewmode.value === "camera" ? [yaw, elevation] : PRESETS[viewmode.value];
// #frame=N opens paused at that frame (of the input: as world files count them); #follow=TRACK follows one person.
const askedFrame = (location.hash.match(/frame=(\\d+)/) || [])[1], \
askedTrack = (location.hash.match(/follow=([^&]+)/) || [])[1];
if (askedFrame !== undefined) { frame = Math.max(0, Math.min(frames - 1, +askedFrame - first)); playing = false;
  document.getElementById("play").textContent = "play"; }
if (askedTrack !== undefined && names.includes(decodeURIComponent(askedTrack))) {
  follow.value = decodeURIComponent(askedTrack); follow.onchange(); }
resize();
</script></body></html>
"""


def floor_ellipses(sequence: np.ndarray | LiftResult, camera) -> np.ndarray | None:
    """(T, 4) the floor-plan ellipse of one sd of each frame's position: its semi-axis along the camera's ray as
    seen from above (the along-ray sd and the vertical across-ray sd, each by its horizontal share), across it,
    and the ray's horizontal direction (x, y); None without an uncertainty or a camera."""
    if not isinstance(sequence, LiftResult) or sequence.position_sd is None or camera is None:
        return None
    ray = sequence.root - np.asarray(camera.center)
    ray /= np.linalg.norm(ray, axis=-1, keepdims=True)
    flat = np.linalg.norm(ray[:, :2], axis=-1, keepdims=True)
    direction = np.where(flat > 1e-9, ray[:, :2] / np.maximum(flat, 1e-9), [1.0, 0.0])
    steep = np.sqrt(np.maximum(1 - flat[:, 0] ** 2, 0.0))  # the vertical across-ray axis, seen from above
    along, across = sequence.position_sd.T
    return np.column_stack([np.hypot(along * flat[:, 0], across * steep), across, direction])


def write_viewer(path: str | Path, sequences: dict[str, np.ndarray | LiftResult], fps: float, camera=None,
                 title: str = "ray3d viewer", overwrite: bool = False, more_cameras=()) -> Path:
    """Write the viewer for {name: world joints (T, 17, 3) or a LiftResult} (metres, z up) played at ``fps``;
    ``more_cameras`` (a fused world's others) are drawn too, each with its field of view and name."""
    tracks = {str(name): as_track(s) for name, s in sequences.items()}
    ellipses = {str(name): floor_ellipses(s, camera) for name, s in sequences.items()}
    stacked = np.concatenate([j.reshape(-1, 3) for _, j, _ in tracks.values()])
    stacked = stacked[np.isfinite(stacked).all(-1)]
    centre = np.median(stacked, axis=0)
    camera_lines = [line.round(4).tolist() for line in frustum_lines(camera)] if camera is not None else []
    others = [{"name": other.name or f"camera {k + 2}", "centre": np.asarray(other.center).round(4).tolist(),
               "lines": [line.round(4).tolist() for line in frustum_lines(other)]}
              for k, other in enumerate(more_cameras)]
    plan = np.concatenate([stacked[:, :2]] + [np.asarray(c.center[:2])[None] for c in
                                              ([camera] if camera is not None else []) + list(more_cameras)])
    data = {
        "sequences": {name: {"start": start, "joints": np.round(joints, 4).tolist(), "filled": filled.tolist(),
                             "sd": None if ellipses[name] is None else np.round(ellipses[name], 4).tolist()}
                      for name, (start, joints, filled) in tracks.items()},
        "first": min(start for start, _, _ in tracks.values()),
        "last": max(start + len(joints) - 1 for start, joints, _ in tracks.values()),
        "fps": float(fps),
        "parents": list(H36M17.parents), "sides": [n[:2] in ("l_", "r_") for n in H36M17.joint_names],
        "colours": [PALETTE[i % len(PALETTE)] for i in range(len(tracks))],
        "centre": [float(centre[0]), float(centre[1])],
        "extent": float(max(1.5, np.percentile(np.abs(stacked[:, :2] - centre[:2]), 98) + 0.5)),
        "bounds": [*plan.min(axis=0).round(3).tolist(), *plan.max(axis=0).round(3).tolist()],
        "camera_lines": camera_lines,
        "more_cameras": others,
        "camera": None if camera is None else {
            "R": np.asarray(camera.R).round(6).tolist(), "t": np.asarray(camera.t).round(6).tolist(),
            **dict(zip(("fx", "fy", "cx", "cy"), camera.K[[0, 1, 0, 1], [0, 1, 2, 2]].astype(float).tolist())),
            "width": int(camera.image_size[0]), "height": int(camera.image_size[1]),
            "centre": np.asarray(camera.center).round(4).tolist()},
    }
    return write_text(path, _TEMPLATE.replace("__TITLE__", title).replace("__DATA__", json.dumps(data)), overwrite)
