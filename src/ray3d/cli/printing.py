"""What several commands print or write the same way: JSON documents, the refinements and the ankle plane of
lifted tracks, a fusion's summary, a site's report. Shared by the handlers, none of which imports another."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from ray3d.body import ADULT_STATURE_M, ADULT_STATURE_SD_M, AXIS_HEIGHTS, PLAUSIBLE_STATURE_M

# A camera below a standing adult's hips whose people come out smaller than nearly every adult: its height (or
# its pitch's sign) is the likelier error than a room of children.
HIP_HEIGHT_M = AXIS_HEIGHTS["pelvis"] * ADULT_STATURE_M
SMALL_STATURE_M = ADULT_STATURE_M - 4 * ADULT_STATURE_SD_M


def write_json(path: Path | None, document: dict, overwrite: bool) -> None:
    """``document`` written to ``path`` (None: not asked for, nothing written), and a line saying so."""
    from ray3d.io.atomic import atomic_path

    if path is None:
        return
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
    """Each track's refinement, and after the work (a refusal stays one line) what is implausible of them and the
    camera."""
    for doubt in () if camera is None else [*camera.doubts()[1], *low_camera_doubts(tracks, camera)]:
        print(f"warning: {doubt}", file=sys.stderr)
    print_ankle_plane(tracks, camera)
    for track, result in tracks.items():
        if result.refinement:
            r = result.refinement
            print(f"  track {track}: stature {r['stature_m']:.2f} m, moved x{r['median_scale']:.2f} along the rays, "
                  f"feet on the floor in {100 * r['contact_fraction']:.0f}% of frames, "
                  f"position +- {r['position_sd_m']:.2f} m")
            low, high = PLAUSIBLE_STATURE_M  # outside it the camera is the likelier error
            if not low <= r["stature_m"] <= high:
                print(f"warning: track {track} comes out {r['stature_m']:.2f} m tall, outside {low}-{high} m: "
                      "check the camera's height, pitch and lens", file=sys.stderr)


def low_camera_doubts(tracks: dict, camera) -> tuple[str, ...]:
    """A camera below a standing adult's hips (``HIP_HEIGHT_M``) whose people's median stature comes out under
    ``SMALL_STATURE_M``: one clause asking for its height and pitch; () otherwise."""
    statures = [r.refinement["stature_m"] for r in tracks.values() if r.refinement and "stature_m" in r.refinement]
    if not statures or camera.camera_height >= HIP_HEIGHT_M or float(np.median(statures)) >= SMALL_STATURE_M:
        return ()
    name = f"camera {camera.name}" if camera.name else "the camera"
    return (f"{name} stands {camera.camera_height:.2f} m over the floor, below a standing adult's hips, and its "
            f"people come out {float(np.median(statures)):.2f} m tall (median of {len(statures)}): is its height in "
            f"metres over the floor, and its pitch's sign (positive looks down, now {np.degrees(camera.pitch):+.0f} "
            "degrees), right?",)


def print_keypoint_notes(path, keypoints) -> None:
    """What reading a keypoint file decided that its user should know, a ``note:`` line on stderr each: how frames
    named by text (image names) were numbered, and the people left out of a file without track ids."""
    if keypoints.frame_order:
        frames = np.unique(keypoints.frames)
        print(f"note: {path} names its frames by text: ordered {keypoints.frame_order}, frames {frames[0]}-"
              f"{frames[-1]} ({len(frames)} of them); if that is not the video's order, give each entry its frame "
              "number", file=sys.stderr)
    if keypoints.untracked_dropped:
        print(f"note: {path} has several people in some frames but no track ids: lifted each frame's most "
              f"confident person, {keypoints.untracked_dropped} other detection(s) left out (give track ids, e.g. "
              "AlphaPose --pose_track, to lift everybody)", file=sys.stderr)


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


def print_places(places: list[dict]) -> None:
    """A line per place (``site.analytics.zone_summaries``' rows): its counts, and how many of them people taken
    up again after a gap made."""
    for row in places:
        tally = (f"{row['entries']} entries, {row['exits']} exits" if row["kind"] == "zone"
                 else f"{row['forward']} forward, {row['back']} back")
        joined = f" ({row['by_rejoined_tracks']} by people taken up again after a gap)" if row["by_rejoined_tracks"] \
            else ""
        print(f"{row['kind']} {row['place']}: {tally}{joined}")


def print_site_report(report, world) -> None:
    """A site's report (``jobs.SiteReport``) of ``world``'s people: the counts per place and the events by kind."""
    print_places(report.places)
    kinds: dict[str, int] = {}
    for event in report.events:
        kinds[event["event"]] = kinds.get(event["event"], 0) + 1
    print(f"{len(report.events)} events of {len(world.tracks)} tracks "
          f"({', '.join(f'{n} {k}' for k, n in kinds.items())}) "
          f"-> {report.folder}: {', '.join(p.name for p in report.files)}")


def print_site_doubts(site_file, plan, cameras=(), world=None, said: frozenset = frozenset()) -> frozenset:
    """One ``warning:`` line on stderr for each place of a site that looks drawn in pixels or away from where the
    cameras (and, given a ``world``, its people) are (``site.checks.site_doubts``), but those already ``said``;
    -> the places said now and before."""
    from ray3d.site.checks import people_places, site_doubts

    doubts = site_doubts(plan, cameras, None if world is None else people_places(world))
    for doubt in doubts:
        if doubt.place not in said:
            print(f"warning: {site_file}: {doubt}", file=sys.stderr)
    return frozenset(said | {doubt.place for doubt in doubts})


def known_cameras(job) -> list:
    """The cameras of a job known before its inputs are opened (a camera placed by its height without an image
    size takes the video's, and is left out)."""
    from ray3d.errors import InputError

    cameras = []
    for choice in job.cameras:
        try:
            cameras.append(choice.camera())
        except InputError:
            pass
    return cameras


def print_notes(notes: list[str]) -> None:
    """A job's notes (``JobResult.notes``), each a line on stderr."""
    for note in notes:
        print(f"note: {note}", file=sys.stderr)
