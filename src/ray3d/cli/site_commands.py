"""``ray3d site`` (and ``ray3d video --site``): a world's tracks on a site's zones and lines, as a report, tables
and plots (``ray3d.viz.site_report.analyse_site``); ``ray3d fuse``: several cameras' worlds as one, the world a
site is read on (``ray3d.fusion``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ray3d.io.atomic import check_output, refuse_existing


def refuse_site_outputs(out_dir: Path, inputs: tuple, overwrite: bool) -> None:
    """Before any work: no output of the site analysis may be an input or exist (unless ``overwrite``)."""
    from ray3d.viz.site_report import site_outputs

    for path in site_outputs(out_dir):
        refuse_existing(check_output(path, inputs), overwrite)


def report_site(world, site, out_dir: Path, title: str, overwrite: bool) -> None:
    """Analyse a ``World`` on a ``ray3d.site.Site`` and print the counts per place and the events by kind."""
    from ray3d.viz.site_report import analyse_site

    events, places, paths = analyse_site(world, site, out_dir, title, overwrite)
    for row in places:
        tally = (f"{row['entries']} entries, {row['exits']} exits" if row["kind"] == "zone"
                 else f"{row['forward']} forward, {row['back']} back")
        print(f"{row['kind']} {row['place']}: {tally}")
    kinds: dict[str, int] = {}
    for event in events:
        kinds[event["event"]] = kinds.get(event["event"], 0) + 1
    print(f"{len(events)} events of {len(world.tracks)} tracks ({', '.join(f'{n} {k}' for k, n in kinds.items())}) "
          f"-> {out_dir}: {', '.join(p.name for p in paths)}")


def site(args: argparse.Namespace) -> int:
    from ray3d.io.site_files import read_site
    from ray3d.io.world import read_world

    refuse_site_outputs(args.out, (args.world, args.site), args.force)
    plan = read_site(args.site)  # a bad site file is refused before the world file is read
    report_site(read_world(args.world), plan, args.out, f"{args.world.name} on {args.site.name}", args.force)
    return 0


def fuse(args: argparse.Namespace) -> int:
    """``ray3d fuse``: several cameras' world files -> one world, one track per person (``ray3d.fusion``)."""

    from ray3d.errors import InputError
    from ray3d.fusion import fuse_worlds
    from ray3d.io.world import read_world, write_world

    refuse_existing(check_output(args.out, tuple(args.worlds)), args.force)
    offsets = None
    if args.offsets:
        try:
            offsets = [float(v) for v in args.offsets.split(",")]
        except ValueError:
            raise InputError(f"--offsets: expected seconds separated by commas, got {args.offsets!r}") from None
    fusion = fuse_worlds([read_world(path) for path in args.worlds], offsets, args.find_offsets, args.max_offset,
                         args.handover)
    write_world(args.out, fusion.world, overwrite=args.force)
    print_fusion(fusion, [str(path) for path in args.worlds])
    print(f"{len(fusion.world.tracks)} people from {len(args.worlds)} cameras -> {args.out}")
    return 0


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
