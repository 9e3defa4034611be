"""``ray3d calibrate``: a camera from floor points or from a person walking, or where a calibrated camera's
floor lies (``ray3d.calibrate``)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ray3d.cli.printing import print_keypoint_notes
from ray3d.errors import InputError
from ray3d.io.atomic import check_output


def _image_size(args: argparse.Namespace) -> tuple[int, int]:
    from ray3d.geometry import parse_image_size

    return parse_image_size(args.image_size, "--image-size")


def calibrate(args: argparse.Namespace) -> int:
    import numpy as np

    from ray3d.calibrate import from_floor_points
    from ray3d.geometry import pinhole_intrinsics
    from ray3d.io.camera_files import read_camera, save_cameras
    from ray3d.io.floor_points import read_floor_points

    if sum(way is not None for way in (args.floor_points, args.from_person, args.floor_of)) != 1:
        raise InputError("calibrate: pass exactly one of --floor-points FILE, --from-person KEYPOINTS and "
                         "--floor-of CAMERA")
    check_output(args.out, (args.floor_points, args.from_person, args.intrinsics, args.floor_of, args.keypoints,
                            args.with_camera, args.with_keypoints))
    if args.from_person is not None:
        return _calibrate_from_person(args)
    if args.floor_of is not None:
        return _calibrate_floor(args)
    floor_xy, pixels = read_floor_points(args.floor_points)
    if args.intrinsics:
        intrinsics, image_size = read_camera(args.intrinsics), None
    else:
        if args.image_size is None or (args.focal is None) == (args.hfov is None):
            raise InputError("calibrate: pass --intrinsics FILE, or --image-size with --focal or --hfov")
        image_size = _image_size(args)
        intrinsics = pinhole_intrinsics(image_size, args.focal, args.hfov)
    camera, rms = from_floor_points(floor_xy, pixels, intrinsics, image_size, name=args.out.stem)
    save_cameras(args.out, [camera], overwrite=args.force, reprojection_rms_px=rms)
    print(f"camera height {camera.camera_height:.3f} m, pitch {np.degrees(camera.pitch):.2f} deg, roll "
          f"{np.degrees(camera.roll):.2f} deg; reprojection RMS {rms:.2f} px over {len(pixels)} floor points -> "
          f"{args.out}")
    return 0


def _calibrate_from_person(args: argparse.Namespace) -> int:
    from ray3d.calibrate import from_person
    from ray3d.geometry import focal_from_hfov
    from ray3d.io.camera_files import save_cameras
    from ray3d.io.keypoints import read_keypoints

    if args.image_size is None:
        raise InputError("calibrate --from-person: pass --image-size WIDTHxHEIGHT (and --focal or --hfov if known)")
    if args.focal is not None and args.hfov is not None:
        raise InputError("calibrate --from-person: pass at most one of --focal and --hfov")
    image_size = _image_size(args)
    focal = args.focal or (focal_from_hfov(image_size[0], args.hfov) if args.hfov is not None else None)
    keypoints = read_keypoints(args.from_person, args.layout)
    people = dict([keypoints.track(args.track)]) if args.track is not None else keypoints.by_track()  # or everybody
    confidences = [d.confidences for d in people.values()]
    result = from_person([d.pixels for d in people.values()], image_size, args.person_height, focal, keypoints.layout,
                         confidences=None if any(c is None for c in confidences) else confidences)
    save_cameras(args.out, [result.camera], overwrite=args.force, calibration="from person",
                 person_height_m=args.person_height, tracks=[str(t) for t in people], **result.to_dict())
    print(f"{result.summary()} (people {args.person_height:.2f} m tall on average) -> {args.out}")
    print_keypoint_notes(args.from_person, keypoints)
    for warning in result.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    return 0


def _calibrate_floor(args: argparse.Namespace) -> int:
    from ray3d.calibrate import floor_from_cameras, floor_from_lens_height
    from ray3d.io.atomic import refuse_existing
    from ray3d.io.camera_files import read_camera, save_camera_with_floor_z

    pair = [given is not None for given in (args.keypoints, args.with_camera, args.with_keypoints)]
    by_tape, by_two_cameras = args.lens_height is not None and not any(pair), args.lens_height is None and all(pair)
    if not (by_tape or by_two_cameras):
        raise InputError("calibrate --floor-of: pass --lens-height M, or --keypoints FILE with --with-camera CAMERA "
                         "and --with-keypoints FILE")
    refuse_existing(args.out, args.force)  # before the work
    camera = read_camera(args.floor_of)
    check = (floor_from_lens_height(camera, args.lens_height) if by_tape
             else floor_from_cameras(*_two_views(args, camera)))
    save_camera_with_floor_z(args.floor_of, args.out, check.floor_z_m, args.force, floor_check=check.to_dict())
    print(f"{check.message(camera.name or Path(args.floor_of).stem)}; written to {args.out}: floor_z_m = "
          f"{check.floor_z_m:.2f}")
    return 0


def _two_views(args: argparse.Namespace, camera) -> tuple[dict, str, float | None]:
    """``floor_from_cameras``' arguments from ``--keypoints`` (seen by ``--floor-of``'s ``camera``) and
    ``--with-keypoints`` (seen by ``--with-camera``): one layout and one frame rate for both."""
    from ray3d.io.camera_files import read_camera
    from ray3d.io.keypoints import read_keypoints

    files = [read_keypoints(path, args.layout, args.fps) for path in (args.keypoints, args.with_keypoints)]
    if files[0].layout != files[1].layout:
        raise InputError(f"{args.keypoints} holds {files[0].layout} keypoints and {args.with_keypoints} "
                         f"{files[1].layout}: triangulated ankles need one detector's", arguments=("layout",))
    rates = {f.fps for f in files if f.fps is not None}
    if len(rates) > 1:
        raise InputError(f"{args.keypoints} and {args.with_keypoints} state frame rates {sorted(rates)}: frames on "
                         "one clock have one rate", arguments=("fps",))
    views = {args.keypoints: (files[0].by_track(), camera),
             args.with_keypoints: (files[1].by_track(), read_camera(args.with_camera))}
    return views, files[0].layout, next(iter(rates), None)
