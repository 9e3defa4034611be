"""The ``ray3d`` command line: argparse over the library (``parser``), one handler per subcommand
(``commands``), and here the exit codes and the one-line errors, with library arguments named by their flags."""

from __future__ import annotations

import io
import os
import sys

from ray3d.errors import InputError

# The flag that sets each library argument an error can name.
FLAGS = {"overwrite": "--force", "resume": "--resume", "out": "--out", "layout": "--layout",
         "camera_index": "--camera-index", "subject": "--subject", "action": "--action", "data_dir": "--data-dir",
         "fps": "--fps", "track": "--track", "focal_px": "--focal", "hfov_deg": "--hfov", "start": "--start",
         "frames": "--frames", "detector": "--detector", "people": "--people", "max_gap_s": "--max-gap",
         "min_track_s": "--min-track", "height_m": "--camera-height", "pitch_deg": "--pitch", "roll_deg": "--roll",
         "checkpoint": "--checkpoint", "stride": "--stride", "frame": "--frame", "floor_points": "--floor-points",
         "manifest": "MANIFEST", "animation": "--animation", "camera": "--camera", "camera_height": "--camera-height",
         "pitch": "--pitch", "roll": "--roll", "image_size": "--image-size", "hfov": "--hfov", "focal": "--focal",
         "smooth_2d": "--smooth-2d", "smooth_3d": "--smooth-3d", "source": "SOURCE", "token": "--token",
         "port": "--port", "page": "--no-page", "offsets": "--offsets", "cameras": "WORLDS", "format": "--format",
         "frame_stride": "--frame-stride", "clips_per_camera": "--clips-per-camera", "max_frames": "--max-frames",
         "floor_offset": "--floor-offset", "camera_step": "--camera-step", "floor_z": "--floor-z",
         "population_scale": "--population-scale",
         "site": "--site", "every_s": "--every", "start_time": "--start-time", "store": "--store", "mqtt": "--mqtt",
         "lens_height_m": "--lens-height", "config": "--config"}
# Where a command calls a library argument by another flag than FLAGS' (``cameras`` is ``ray3d fuse``'s WORLDS).
COMMAND_FLAGS = {"evaluate": {"model": "--checkpoint", "cameras": "--cameras", "given_cameras": "--cameras",
                              "joints": "--joints", "refine": "--refine", "noise_px": "--noise-px",
                              "precision": "--precision"}}


def main(argv: list[str] | None = None) -> int:
    from ray3d.cli.parser import build_parser

    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        if args.command == "live" and args.config is not None:  # a deployment in one file
            from ray3d.cli.live_config import with_config
            from ray3d.cli.parser import subcommand_parser

            args = with_config(parser, subcommand_parser(parser, args.command), argv, args.config)
        return args.handler(args)
    except InputError as err:
        print(f"ray3d {args.command}: error: {err.message_for({**FLAGS, **COMMAND_FLAGS.get(args.command, {})})}",
              file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"ray3d {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # whoever read the output stopped (`| head`): not a bug; stop as a SIGPIPE would
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error flushing at exit
        except (OSError, ValueError, io.UnsupportedOperation):
            pass
        return 141
    except Exception as err:
        if args.debug:
            raise
        if isinstance(err, OSError) and err.filename is not None:
            # A path the system refused (too long, not permitted, a full disk): the user's to mend.
            print(f"ray3d {args.command}: error: {str(err.filename)[:200]}: {err.strerror or type(err).__name__}",
                  file=sys.stderr)
            return 2
        # A bug, not bad input: one line and how to report it, the traceback with --debug.
        print(f"ray3d {args.command}: internal error: {type(err).__name__}: {err} -- this is a bug in ray3d; "
              "please report it with the command (run again with --debug for the traceback)", file=sys.stderr)
        return 1
