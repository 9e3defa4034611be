"""A site's HTML page, self-contained and offline (``ray3d.site.report`` writes it with the tables and plots):
the floor plan (paths, time spent, zones, lines), the counts per place, zone occupancy, a timeline of every event,
and the events' table, each event linking to the 3D viewer (written beside it) opened at its moment and following
its person."""

from __future__ import annotations

import base64
import html
import json
from pathlib import Path

from ray3d.io.atomic import write_text

_HEAD = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>__TITLE__</title>
<style>
 body { font-family: sans-serif; margin: 16px; background: #fafafa; }
 img { max-width: 48%; border: 1px solid #ddd; background: #fff; margin-right: 1%; vertical-align: top; }
 table { border-collapse: collapse; margin: 8px 0 16px; font-size: 13px; }
 td, th { border: 1px solid #ccc; padding: 3px 8px; text-align: left; }
 .note { color: #555; }
 __MORE_STYLE__
</style></head>
<body>
<h1>__TITLE__</h1>
<p class="note">__NOTE__</p>
"""  # the head and title both pages share

_TEMPLATE = _HEAD.replace("__MORE_STYLE__", "#timeline { width: 100%; height: 160px; background: #fff; "
                           "border: 1px solid #ddd; display: block; }") + """<h2>Floor plan and occupancy</h2>
<img id="plan" alt="floor plan" src="data:image/png;base64,__PLAN__">\
<img id="occupancy" alt="occupancy" src="data:image/png;base64,__OCCUPANCY__">
<h2>Places</h2>
__PLACES__
__BY_TIME__
<h2>Timeline</h2>
<canvas id="timeline"></canvas>
<p class="note" id="legend"></p>
<h2>Events</h2>
<p class="note">Each event opens the 3D viewer (viewer.html) at its frame, following its person.</p>
<table id="events"><tr><th>time (s)</th><th>event</th><th>track</th><th>where</th><th>details</th></tr></table>
<script>
const EVENTS = __EVENTS__, COLOURS = __COLOURS__, FPS = __FPS__;
const table = document.getElementById("events");
EVENTS.forEach(e => {
  const row = table.insertRow(), frame = (e.frames || [Math.round(e.time_s * FPS)]).slice(-1)[0];
  const link = `viewer.html#frame=${frame}&follow=${encodeURIComponent(e.track)}`;
  const details = Object.entries(e).filter(([k]) => !["event", "track", "time_s", "frames", "place_m"].includes(k))
    .map(([k, v]) => `${k}: ${JSON.stringify(v)}`).join("; ");
  [e.time_s.toFixed(2), `<a href="${link}">${e.event}</a>`, e.track, e.line || e.zone || (e.place_m || []).join(", "),
   details].forEach(text => { row.insertCell().innerHTML = text; });
});
const canvas = document.getElementById("timeline"), ctx = canvas.getContext("2d");
function drawTimeline() {
  canvas.width = canvas.clientWidth; canvas.height = canvas.clientHeight;
  const kinds = Object.keys(COLOURS), end = Math.max(1e-3, ...EVENTS.map(e => e.time_s)), left = 150;
  ctx.fillStyle = "#fff"; ctx.fillRect(0, 0, canvas.width, canvas.height); ctx.font = "11px sans-serif";
  kinds.forEach((kind, k) => {
    const y = 10 + k * (canvas.height - 20) / kinds.length;
    ctx.fillStyle = "#444"; ctx.fillText(kind, 4, y + 8);
    ctx.fillStyle = COLOURS[kind];
    EVENTS.filter(e => e.event === kind).forEach(e =>
      ctx.fillRect(left + (canvas.width - left - 10) * e.time_s / end - 2, y, 4, 12));
  });
  ctx.fillStyle = "#444"; ctx.fillText(`0 s`, left, canvas.height - 2);
  ctx.fillText(`${end.toFixed(1)} s`, canvas.width - 50, canvas.height - 2);
}
document.getElementById("legend").textContent = `${EVENTS.length} events over time, one row per kind`;
window.onresize = drawTimeline; drawTimeline();
</script></body></html>
"""


def _table(rows: list[dict]) -> str:
    columns = list(dict.fromkeys(key for row in rows for key in row))
    head = "".join(f"<th>{html.escape(c)}</th>" for c in columns)
    body = "".join("<tr>" + "".join(f"<td>{html.escape('' if row.get(c) is None else str(row.get(c)))}</td>"
                                    for c in columns) + "</tr>" for row in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def write_site_report(path: str | Path, events: list[dict], places: list[dict], plan_png: Path, occupancy_png: Path,
                      fps: float, colours: dict[str, str], title: str = "ray3d site report", note: str = "",
                      overwrite: bool = False, buckets: list[dict] | None = None) -> Path:
    """The report at ``path``, the two plots embedded in it (and the counts per time bucket, when given), each
    kind of event on the timeline in its colour (``colours``: {event name: CSS colour}); its events link to
    ``viewer.html`` beside it."""
    def embedded(png: Path) -> str:
        return base64.b64encode(Path(png).read_bytes()).decode("ascii")

    page = (_TEMPLATE.replace("__TITLE__", html.escape(title)).replace("__NOTE__", html.escape(note))
            .replace("__PLAN__", embedded(plan_png)).replace("__OCCUPANCY__", embedded(occupancy_png))
            .replace("__PLACES__", _table(places))
            .replace("__BY_TIME__", f"<h2>By time</h2>{_table(buckets)}" if buckets else "")
            .replace("__COLOURS__", json.dumps(colours))
            .replace("__FPS__", json.dumps(float(fps))).replace("__EVENTS__", json.dumps(events).replace("</", "<\\/")))
    return write_text(path, page, overwrite)


_RECORD_TEMPLATE = _HEAD.replace("__MORE_STYLE__", "td.n { text-align: right; font-variant-numeric: "
                                 "tabular-nums; }") + """<h2>Places</h2>
__PLACES__
<h2>Events by kind</h2>
__KINDS__
<h2>Floor plan</h2>
<img id="plan" alt="floor plan: time spent" src="data:image/png;base64,__PLAN__">
__BY_TIME__
<h2>Gaps in the record</h2>
__GAPS__
</body></html>
"""


def _numbers_table(rows: list[dict]) -> str:
    """A table whose numbers are right-aligned, as given (already rounded)."""
    if not rows:
        return "<p class='note'>none</p>"
    columns = list(dict.fromkeys(key for row in rows for key in row))
    head = "".join(f"<th>{html.escape(c)}</th>" for c in columns)

    def cell(value) -> str:
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        return f"<td class='n'>{value}</td>" if number else \
            f"<td>{html.escape('' if value is None else str(value))}</td>"

    body = "".join("<tr>" + "".join(cell(row.get(c)) for c in columns) + "</tr>" for row in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def write_record_report(path: str | Path, title: str, note: str, places: list[dict], kinds: dict[str, int],
                        gaps: list[dict], plan_png: Path, by_time_png: Path | None, buckets: list[dict] | None,
                        overwrite: bool = False) -> Path:
    """A store's report at ``path`` (``ray3d.site.record``): the places' counts, the events by kind, the floor
    plan, the chart and table by time (when given) and the gaps, self-contained."""
    def embedded(png: Path) -> str:
        return base64.b64encode(Path(png).read_bytes()).decode("ascii")

    by_time = "" if buckets is None else (
        f"<h2>By time</h2><img id='by-time' alt='counts and occupancy by time' style='max-width: 98%' "
        f"src='data:image/png;base64,{embedded(by_time_png)}'>{_numbers_table(buckets)}")
    page = (_RECORD_TEMPLATE.replace("__TITLE__", html.escape(title)).replace("__NOTE__", html.escape(note))
            .replace("__PLACES__", _numbers_table(places))
            .replace("__KINDS__", _numbers_table([{"event": k, "count": n} for k, n in kinds.items()]))
            .replace("__PLAN__", embedded(plan_png)).replace("__BY_TIME__", by_time)
            .replace("__GAPS__", _numbers_table(gaps)))
    return write_text(path, page, overwrite)
