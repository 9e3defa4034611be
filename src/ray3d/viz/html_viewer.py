"""A self-contained, offline HTML viewer of 3D sequences: orbit (drag), zoom (wheel), play/pause, a frame
slider, and several methods side by side (each in its own colour over a shared ground grid)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ray3d.io.atomic import atomic_path
from ray3d.skeleton import H36M17

PALETTE = ("#d62f2f", "#1f5fd6", "#2a9d3c", "#9c27b0", "#ef8a00", "#555555")

_TEMPLATE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>__TITLE__</title>
<style>
 body { font-family: sans-serif; margin: 0; background: #fafafa; }
 #bar { padding: 8px; display: flex; gap: 12px; align-items: center; flex-wrap: wrap; }
 #view { display: block; background: #ffffff; border-top: 1px solid #ddd; cursor: grab; }
 .key { display: inline-block; width: 14px; height: 4px; margin-right: 4px; vertical-align: middle; }
</style></head>
<body>
<div id="bar">
 <button id="play">pause</button>
 <input id="slider" type="range" min="0" value="0" style="width: 40%">
 <span id="label"></span>
 <span id="legend"></span>
 <span style="color: #777">drag to orbit, wheel to zoom; metres, z up</span>
</div>
<canvas id="view" width="960" height="600"></canvas>
<script>
const DATA = __DATA__;
const canvas = document.getElementById("view"), ctx = canvas.getContext("2d");
const slider = document.getElementById("slider"), label = document.getElementById("label");
const names = Object.keys(DATA.sequences), frames = DATA.frames;
slider.max = frames - 1;
let frame = 0, playing = true, yaw = -0.6, elevation = 0.35, zoom = 1.0;
document.getElementById("legend").innerHTML = names.map((n, i) =>
  `<span class="key" style="background:${DATA.colours[i]}"></span>${n}`).join(" &nbsp; ");
function project(p) {
  const x = p[0] - DATA.centre[0], y = p[1] - DATA.centre[1], z = p[2];
  const cx = Math.cos(yaw) * x - Math.sin(yaw) * y, cy = Math.sin(yaw) * x + Math.cos(yaw) * y;
  const depth = Math.cos(elevation) * cy + Math.sin(elevation) * z;
  const up = -Math.sin(elevation) * cy + Math.cos(elevation) * z;
  const scale = zoom * canvas.height / (2.2 * DATA.extent);
  return [canvas.width / 2 + scale * cx, canvas.height * 0.75 - scale * up, depth];
}
function line(a, b, colour, width) {
  const p = project(a), q = project(b);
  ctx.strokeStyle = colour; ctx.lineWidth = width;
  ctx.beginPath(); ctx.moveTo(p[0], p[1]); ctx.lineTo(q[0], q[1]); ctx.stroke();
}
function draw() {
  ctx.fillStyle = "#ffffff"; ctx.fillRect(0, 0, canvas.width, canvas.height);
  const g = DATA.extent, c = DATA.centre;
  for (let k = -g; k <= g + 1e-9; k += 0.5) {
    line([c[0] + k, c[1] - g, 0], [c[0] + k, c[1] + g, 0], "#e3e3e3", 1);
    line([c[0] - g, c[1] + k, 0], [c[0] + g, c[1] + k, 0], "#e3e3e3", 1);
  }
  DATA.camera_lines.forEach(s => line(s[0], s[1], "#999999", 1));
  names.forEach((name, i) => {
    const seq = DATA.sequences[name], pose = seq[Math.min(frame, seq.length - 1)];
    for (let t = 1; t <= Math.min(frame, seq.length - 1); t++)
      line([seq[t - 1][0][0], seq[t - 1][0][1], 0], [seq[t][0][0], seq[t][0][1], 0], DATA.colours[i], 1);
    DATA.parents.forEach((p, j) => { if (p >= 0) line(pose[j], pose[p], DATA.colours[i], DATA.sides[j] ? 3 : 2); });
  });
  label.textContent = `frame ${frame + 1} / ${frames}`;
  slider.value = frame;
}
document.getElementById("play").onclick = e => { playing = !playing; e.target.textContent = playing ? "pause" : "play"; };
slider.oninput = () => { frame = +slider.value; draw(); };
let drag = null;
canvas.onmousedown = e => { drag = [e.clientX, e.clientY, yaw, elevation]; };
window.onmouseup = () => { drag = null; };
window.onmousemove = e => { if (!drag) return;
  yaw = drag[2] - (e.clientX - drag[0]) * 0.01;
  elevation = Math.max(-0.2, Math.min(1.5, drag[3] + (e.clientY - drag[1]) * 0.01)); draw(); };
canvas.onwheel = e => { e.preventDefault(); zoom *= e.deltaY < 0 ? 1.1 : 0.9; draw(); };
setInterval(() => { if (playing) { frame = (frame + 1) % frames; draw(); } }, 1000 / DATA.fps);
draw();
</script></body></html>
"""


def write_viewer(path: str | Path, sequences: dict[str, np.ndarray], fps: float, camera=None,
                 title: str = "ray3d viewer", overwrite: bool = False) -> Path:
    """Write the viewer for {method name: world joints (T, 17, 3)} (metres, z up)."""
    from ray3d.viz.animation import frustum_lines

    stacked = np.concatenate([s.reshape(-1, 3) for s in sequences.values()])
    centre = np.median(stacked, axis=0)
    data = {
        "sequences": {name: np.round(s, 4).tolist() for name, s in sequences.items()},
        "frames": max(len(s) for s in sequences.values()), "fps": fps,
        "parents": list(H36M17.parents), "sides": [n[:2] in ("l_", "r_") for n in H36M17.joint_names],
        "colours": list(PALETTE[: len(sequences)]) if len(sequences) <= len(PALETTE) else None,
        "centre": [float(centre[0]), float(centre[1])],
        "extent": float(max(1.5, np.abs(stacked[:, :2] - centre[:2]).max() + 0.5)),
        "camera_lines": [line.round(4).tolist() for line in frustum_lines(camera)] if camera is not None else [],
    }
    html = _TEMPLATE.replace("__TITLE__", title).replace("__DATA__", json.dumps(data))
    path = Path(path)
    with atomic_path(path, overwrite) as temporary:
        temporary.write_text(html)
    return path
