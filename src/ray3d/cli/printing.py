"""What several commands print or write the same way: JSON documents, the refinements and the ankle plane of
lifted tracks, a fusion's summary, a site's report. Shared by the handlers, none of which imports another."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ray3d.body import PLAUSIBLE_STATURE_M


def write_json(path: Path, document: dict, overwrite: bool) -> None:
    from ray3d.io.atomic import atomic_path

    with atomic_path(path, overwrite=overwrite) as temporary:
        temporary.write_text(json.dumps(document, indent=1))
    print(f"wrote {path}")


def print_ankle_plane(tracks: dict, camera=None) -> None:
    """One line on stderr: where the tracks' ankles were found to meet the camera's floor, and what was applied."""
    from ray3d.refine import AnklePlane

    planes = [r.refinement["ankle_plane"] for r in tracks.values() if r.refinement and "ankle_plane" in r.refinement]
    if planes:
        print(f"note: {AnklePlane.from_summary(planes[0]).message(getattr(camera, 'name', ''))}", file=sys.stderr)


def print_refinements(tracks: dict, camera=None) -> None:
    """Each track's refinement, and after the work (a refusal stays one line) what is implausible of them and the camera."""
    for doubt in () if camera is None else camera.doubts()[1]:
        print(f"warning: {doubt}", file=sys.stderr)
    print_ankle_plane(tracks, camera)
    for track, result in tracks.items():
        if result.refinement:
            r = result.refinement
            print(f"  track {track}: stature {r['stature_m']:.2f} m, moved x{r['median_scale']:.2f} along the rays, "
                  f"feet on the floor in {100 * r['contact_fraction']:.0f}% of frames, position +- {r['position_sd_m']:.2f} m")
            low, high = PLAUSIBLE_STATURE_M  # outside it the camera is the likelier error
            if not low <= r["stature_m"] <= high:
                print(f"warning: track {track} comes out {r['stature_m']:.2f} m tall, outside {low}-{high} m: check the "
                      "camera's height, pitch and lens", file=sys.stderr)


def print_fusion(fusion, sources: list[str]) -> None:
    """The offsets, who joined whom, the cameras' agreement, and a warning on stderr naming a camera that
    disagrees."""
    import sys

    for source, offset, sd in zip(sources, fusion.offsets_s, fusion.offset_sd_s):
        print(f"{source}: offset {offset:+.3f} s" + (f" +- {sd:.3f} s (found)" if sd else ""))
    for track, members in fusion.members.items():
        print(f"  person {track}: {', '.join(members)}")
    for entry in fusion.agreement:
        print(f"  {entry['cameras'][0]} and {entry['cameras'][1]}: the same person {entry['median_distance_m']:.2f} m "
              f"apart, {entry['median_sigmas']:.1f} sd of their uncertainties (median of {entry['frames']} frames)")
    if fusion.suspects():
        print(f"warning: the cameras disagree on where people are beyond their uncertainties; check the calibration "
              f"of {' and '.join(fusion.suspects())}", file=sys.stderr)


def print_site_report(report, world) -> None:
    """A site's report (``jobs.SiteReport``) of ``world``'s people: the counts per place and the events by kind."""
    for row in report.places:
        tally = (f"{row['entries']} entries, {row['exits']} exits" if row["kind"] == "zone"
                 else f"{row['forward']} forward, {row['back']} back")
        joined = f" ({row['by_rejoined_tracks']} by people taken up again after a gap)" if row["by_rejoined_tracks"] \
            else ""
        print(f"{row['kind']} {row['place']}: {tally}{joined}")
    kinds: dict[str, int] = {}
    for event in report.events:
        kinds[event["event"]] = kinds.get(event["event"], 0) + 1
    print(f"{len(report.events)} events of {len(world.tracks)} tracks ({', '.join(f'{n} {k}' for k, n in kinds.items())}) "
          f"-> {report.folder}: {', '.join(p.name for p in report.files)}")
