"""The ``ray3d`` command line: a thin layer of argparse over the library; every command is a library call."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import ray3d
from ray3d.errors import InputError


def _demo(args: argparse.Namespace) -> int:
    from ray3d.demo import format_report, run_demo

    print(format_report(run_demo(args.out, args.checkpoint, frames=args.frames)))
    return 0


def _data_info(args: argparse.Namespace) -> int:
    from ray3d.data import motion
    from ray3d.data.virtual_cameras import SET_NAMES, grid

    data_dir = motion.resolve_data_dir(args.data_dir)
    info = motion.summary(motion.load_shipped(data_dir))
    print(f"motion data: {data_dir}")
    print(f"  {info['clips']} clips, {info['frames']:,} frames, {info['minutes']:.1f} minutes (H36M-17, 60 fps)")
    for title, key in (("split (by performer)", "splits"), ("performer", "performers"), ("body", "bodies")):
        print(f"\n  {title:<22}{'clips':>7}{'frames':>10}{'minutes':>9}")
        for name, row in sorted(info[key].items()):
            print(f"  {name:<22}{row['clips']:>7}{row['frames']:>10,}{row['minutes']:>9.1f}")
    print("\n  test performers: " + ", ".join(motion.SPLITS["test"]) + "; validation: "
          + ", ".join(motion.SPLITS["validation"]))
    print("\ncamera sets (before the in-image filter): "
          + ", ".join(f"{name} {len(grid(name))}" for name in SET_NAMES))
    return 0


def _import_common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", required=True, type=Path, help="output motion npz (the shipped format)")
    parser.add_argument("--fps", type=float, default=60.0, help="output frame rate (default 60)")
    parser.add_argument("--drop-frames", type=int, default=0, metavar="N",
                        help="leading native frames to discard, e.g. a synthetic T-pose")
    parser.add_argument("--no-floor", action="store_true", help="keep z as in the file (no floor at z = 0)")
    parser.add_argument("--subject", default="user", help="performer name stored with the clips")
    parser.add_argument("--force", action="store_true", help="replace OUT if it exists")


def _write_imported(args: argparse.Namespace, clips, files: list[Path], source: str) -> int:
    from ray3d.data.importers import clips_to_motion_set

    motion = clips_to_motion_set(clips, [f.stem for f in files], args.subject, source)
    motion.save(args.out, overwrite=args.force)
    minutes = motion.num_frames / args.fps / 60
    print(f"wrote {args.out}: {motion.num_clips} clip(s), {motion.num_frames} frames ({minutes:.2f} min) at "
          f"{args.fps:g} fps; floor offsets {', '.join(f'{c.floor_offset_m:+.3f}' for c in clips)} m")
    return 0


def _import_bvh(args: argparse.Namespace) -> int:
    from ray3d.data.importers import import_bvh

    clips = [import_bvh(f, args.fps, args.drop_frames, not args.no_floor, args.units) for f in args.files]
    return _write_imported(args, clips, args.files, "user_bvh")


def _import_amc(args: argparse.Namespace) -> int:
    from ray3d.data.importers import import_amc

    clips = [import_amc(args.asf, f, args.fps, args.native_fps, args.drop_frames, not args.no_floor)
             for f in args.amc]
    return _write_imported(args, clips, args.amc, "user_amc")


def _cameras(args: argparse.Namespace) -> int:
    from ray3d.data import motion
    from ray3d.data.virtual_cameras import camera_set, centre_clip, grid
    from ray3d.io.camera_files import save_cameras

    if args.no_filter:
        cams, note = grid(args.set), "not filtered"
    else:
        clips = motion.load_shipped(args.data_dir, args.split)
        centred = [centre_clip(clips.clip(i)) for i in range(clips.num_clips)]
        cams = camera_set(args.set, centred)
        note = f"kept cameras that see every joint of all {clips.num_clips} {args.split} clips (centred)"
    save_cameras(args.out, cams, overwrite=args.force, set=args.set, filter=note)
    print(f"wrote {args.out}: {len(cams)} of {len(grid(args.set))} '{args.set}' cameras ({note})")
    return 0


def _samples_speed(args: argparse.Namespace) -> int:
    from ray3d.data import motion
    from ray3d.data.samples import SampleConfig, measure_throughput
    from ray3d.data.virtual_cameras import CameraRanges

    train = motion.load_shipped(args.data_dir, "train")
    configs = {
        "pinhole, clean 2D": SampleConfig(frames=args.frames),
        "pinhole, 2 px noise + 5% dropped": SampleConfig(frames=args.frames, noise_px=2.0, drop_probability=0.05),
        "distortion + roll, 2 px noise": SampleConfig(frames=args.frames, noise_px=2.0, cameras=CameraRanges(
            distortion_k1=(-0.25, 0.0), roll_deg=5.0)),
    }
    print(f"training-sample generator: batch {args.batch} windows of {args.frames} frames, median of {args.repeats}")
    for name, config in configs.items():
        result = measure_throughput(train, config, args.batch, args.repeats)
        print(f"  {name:<36}{result['ms_per_batch']:8.1f} ms/batch{result['samples_per_s']:10,.0f} samples/s")
    return 0


def _train(args: argparse.Namespace) -> int:
    import dataclasses

    from ray3d.models import preset
    from ray3d.train import TrainConfig, train

    config = TrainConfig.from_json(args.config) if args.config else TrainConfig()
    if args.preset:
        config = dataclasses.replace(config, model=preset(args.preset))
        config.__post_init__()
    overrides = {k: v for k, v in (("epochs", args.epochs), ("batches_per_epoch", args.batches_per_epoch),
                                   ("batch_size", args.batch_size), ("seed", args.seed), ("threads", args.threads),
                                   ("data_dir", args.data_dir)) if v is not None}
    config = dataclasses.replace(config, **overrides)
    state = train(config, args.out, resume=args.resume, progress=not args.quiet)
    best = state["best"]
    if best is None:  # a data-parallel worker other than rank 0: it neither validates nor reports
        return 0
    print(f"best epoch {best['epoch']}: validation Abs-MPJPE {best['abs_mpjpe_mm']:.1f} mm, MPJPE "
          f"{best['mpjpe_mm']:.1f} mm, MRPE {best['mrpe_mm']:.1f} mm -> {Path(args.out) / 'best.safetensors'}")
    return 0


def _evaluate(args: argparse.Namespace) -> int:
    import json

    from ray3d.data import motion as motion_data
    from ray3d.data.virtual_cameras import SET_NAMES, grid
    from ray3d.evaluate import METRICS, evaluate
    from ray3d.io.atomic import atomic_path
    from ray3d.io.camera_files import load_cameras

    if args.mocap is None:
        datasets = tuple(args.datasets.split(",")) if args.datasets else tuple(motion_data.DATASETS)
        clips = motion_data.load_shipped(args.data_dir, args.split or "test", datasets)
        source = f"shipped mocap ({', '.join(datasets)}), {args.split or 'test'} performers"
    else:
        clips = motion_data.MotionSet.load(args.mocap)
        shipped = args.mocap.name in motion_data.SHIPPED_FILES
        split = args.split or ("test" if shipped else "all")
        clips = motion_data.select_split(clips, split)
        source = f"{args.mocap} ({split} clips)"
    if clips.num_clips == 0:
        raise InputError(f"{source}: no clips to evaluate")
    cameras = grid(args.cameras) if args.cameras in SET_NAMES else load_cameras(args.cameras)
    result = evaluate(args.checkpoint, clips, cameras, args.flip_test, args.frame_stride, joints=args.joints,
                      noise_px=args.noise_px)
    result = {"model": args.checkpoint, "mocap": source, "cameras": args.cameras, **result}
    print(f"{args.checkpoint} on {source}, cameras {args.cameras}: {result['pairs']} (camera, clip) pairs, "
          f"{result['skipped_pairs']} skipped (not fully in view), {result['frames']:,} frames")
    header = "".join(f"{k.removesuffix('_mm'):>12}" for k in METRICS)
    print(f"{'camera':<36}{header}{'frames':>10}")

    def row(name: str, values: dict) -> str:
        cells = "".join(f"{values[k]:>12.1f}" if values[k] is not None else f"{'-':>12}" for k in METRICS)
        return f"{name:<36}{cells}{values['frames']:>10,}"

    for name, values in result["per_camera"].items():
        print(row(name, values))
    print(row("overall (mm)", result))
    if args.json:
        with atomic_path(args.json, overwrite=args.force) as temporary:
            temporary.write_text(json.dumps(result, indent=1))
        print(f"wrote {args.json}")
    return 0


def _export(args: argparse.Namespace) -> int:
    from ray3d.checkpoints import export, load_model

    if args.onnx:
        from ray3d.io.atomic import atomic_path
        from ray3d.models.backends import export_onnx

        with atomic_path(args.out, overwrite=args.force) as temporary:
            export_onnx(load_model(args.checkpoint)[0], str(temporary), args.image_width)
        print(f"wrote {args.out} (ONNX, opset 17, inputs pixels/rays/camera_params/intrinsics/roll, batch axis dynamic)")
        return 0

    provenance = {"training": {"command": args.command_line, "time_s": args.time_s, "machine": args.machine}} \
        if args.command_line else {}
    target = export(args.checkpoint, args.out, overwrite=args.force, **provenance)
    print(f"wrote {target} and {target.with_suffix('.json')}")
    return 0


def _models(args: argparse.Namespace) -> int:
    from ray3d.checkpoints import shipped_models
    from ray3d.models import PRESETS, LiftingNetwork
    from ray3d.models.network import count_parameters, flops_per_frame

    print(f"{'preset':<15}{'frames':>7}{'params':>12}{'MFLOPs/frame':>14}  {'input':<15}{'backbone':<9}{'root':<12}"
          f"{'camera emb.':<12}shipped")
    shipped = set(shipped_models())
    for name, config in PRESETS.items():
        model = LiftingNetwork(config)
        print(f"{name:<15}{config.frames:>7}{count_parameters(model):>12,}{flops_per_frame(model) / 1e6:>14.2f}  "
              f"{config.input:<15}{config.backbone:<9}{config.root:<12}{'yes' if config.camera_embedding else 'no':<12}"
              f"{'yes' if name in shipped else 'no'}")
    return 0


def _camera_from_args(args: argparse.Namespace):
    from ray3d.geometry import Camera
    from ray3d.io.camera_files import read_camera

    if args.camera:
        return read_camera(args.camera)
    if args.camera_height is None or args.pitch is None or args.image_size is None:
        raise InputError("pass --camera FILE, or --camera-height, --pitch, --image-size and --hfov or --focal")
    return Camera.from_height_pitch(args.camera_height, args.pitch, _image_size(args.image_size), args.roll,
                                    args.focal, args.hfov)


def _image_size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise InputError(f"--image-size: expected WIDTHxHEIGHT, e.g. 1920x1080, got {text!r}") from None
    return width, height


def _add_lens_arguments(parser: argparse.ArgumentParser, role: str, image_size_note: str = "") -> None:
    parser.add_argument("--hfov", type=float, help=f"{role}: horizontal field of view in degrees")
    parser.add_argument("--focal", type=float, help=f"{role}: focal length in pixels (instead of --hfov)")
    parser.add_argument("--image-size", help=f"{role}: WIDTHxHEIGHT in pixels{image_size_note}")


def _add_camera_arguments(parser: argparse.ArgumentParser, image_size_note: str = "") -> None:
    parser.add_argument("--camera", help="camera JSON (ours or OpenCV), OpenCV YAML, or h36m:SUBJECT:CAMERA_ID")
    parser.add_argument("--camera-height", type=float, help="instead of --camera: camera height above the floor, m")
    parser.add_argument("--pitch", type=float, help="instead of --camera: degrees the camera looks down")
    parser.add_argument("--roll", type=float, default=0.0, help="with --pitch: camera roll in degrees (default 0)")
    _add_lens_arguments(parser, "with --pitch", image_size_note)


def _add_lifting_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--checkpoint", default="ray3d", help="shipped model name or checkpoint path (default ray3d)")
    parser.add_argument("--smooth-2d", choices=["savgol", "one-euro"], help="smooth the 2D input in time")
    parser.add_argument("--smooth-3d", choices=["savgol", "one-euro"], help="smooth the 3D output in time")
    parser.add_argument("--flip-test", action="store_true", help="average with the mirrored input's prediction")


def _calibrate(args: argparse.Namespace) -> int:
    import numpy as np

    from ray3d.calibrate import from_floor_points, read_floor_points
    from ray3d.io.camera_files import save_cameras

    if (args.floor_points is None) == (args.from_person is None):
        raise InputError("calibrate: pass exactly one of --floor-points FILE and --from-person KEYPOINTS")
    if args.from_person is not None:
        return _calibrate_from_person(args)
    floor_xy, pixels = read_floor_points(args.floor_points)
    if args.intrinsics:
        from ray3d.io.camera_files import read_camera

        intrinsics, image_size = read_camera(args.intrinsics), None
    else:
        from ray3d.geometry.camera import focal_from_hfov

        if args.image_size is None or (args.focal is None) == (args.hfov is None):
            raise InputError("calibrate: pass --intrinsics FILE, or --image-size with --focal or --hfov")
        width, height = image_size = _image_size(args.image_size)
        focal = args.focal or focal_from_hfov(width, args.hfov)
        intrinsics = (focal, focal, width / 2, height / 2)
    camera, rms = from_floor_points(floor_xy, pixels, intrinsics, image_size, name=args.out.stem)
    save_cameras(args.out, [camera], overwrite=args.force, reprojection_rms_px=rms)
    print(f"camera height {camera.camera_height:.3f} m, pitch {np.degrees(camera.pitch):.2f} deg, roll "
          f"{np.degrees(camera.roll):.2f} deg; reprojection RMS {rms:.2f} px over {len(pixels)} floor points -> {args.out}")
    return 0


def _video(args: argparse.Namespace) -> int:
    from ray3d.lift import Lifter
    from ray3d.video import lift_video, make_detector, read_video_info

    info = read_video_info(args.input)
    if args.camera is None and args.image_size is None:
        args.image_size = f"{info.image_size[0]}x{info.image_size[1]}"
    camera = _camera_from_args(args)
    detector = make_detector(args.detector)
    result = lift_video(args.input, camera, args.out, detector, Lifter.load(args.checkpoint), fps=args.fps,
                        world_format=args.format, overlay=not args.no_overlay, overwrite=args.force,
                        smooth_2d=args.smooth_2d, smooth_3d=args.smooth_3d, flip_test=args.flip_test)
    found = int((result.confidences > 0).any(axis=1).sum())
    print(f"{args.input}: {len(result.keypoints)} frames, a person found in {found}; "
          f"{100 * result.lifted.missing_fraction:.1f}% of joints filled in from neighbouring frames")
    for role, path in result.files.items():
        print(f"  {role:<10}{path}")
    return 0


def _calibrate_from_person(args: argparse.Namespace) -> int:
    import numpy as np

    from ray3d.calibrate import from_person
    from ray3d.geometry.camera import focal_from_hfov
    from ray3d.io.camera_files import save_cameras
    from ray3d.io.keypoints import read_keypoints

    if args.image_size is None:
        raise InputError("calibrate --from-person: pass --image-size WIDTHxHEIGHT (and --focal or --hfov if known)")
    if args.focal is not None and args.hfov is not None:
        raise InputError("calibrate --from-person: pass at most one of --focal and --hfov")
    image_size = _image_size(args.image_size)
    focal = args.focal or (focal_from_hfov(image_size[0], args.hfov) if args.hfov is not None else None)
    keypoints = read_keypoints(args.from_person, args.layout)
    tracks = keypoints.by_track()
    track = args.track if args.track is not None else max(tracks, key=lambda t: len(tracks[t][0]))
    if track not in tracks:
        raise InputError(f"{args.from_person}: no track {track!r}; tracks: {', '.join(map(str, tracks))}")
    _, pixels, confidences = tracks[track]
    if confidences is not None:
        pixels = np.where((confidences > 0)[..., None], pixels, np.nan)
    result = from_person(pixels, image_size, args.person_height, focal, keypoints.layout)
    save_cameras(args.out, [result.camera], overwrite=args.force, calibration="from person",
                 person_height_m=args.person_height, track=str(track), **result.to_dict())
    print(f"{result.summary()} (person {args.person_height:.2f} m tall, track {track}) -> {args.out}")
    return 0


def _lift(args: argparse.Namespace) -> int:
    from ray3d.io.exports import write_world
    from ray3d.io.keypoints import read_keypoints
    from ray3d.lift import Lifter

    if args.out.exists() and not args.force:
        raise InputError(f"{args.out}: already exists; refusing to overwrite it (use --force to replace it)")
    keypoints = read_keypoints(args.keypoints, args.layout, args.fps, subject=args.subject, action=args.action,
                               camera_index=args.camera_index)
    camera = _camera_from_args(args)
    lifter = Lifter.load(args.checkpoint)
    results = lifter.lift_tracks(keypoints.by_track(), camera, keypoints.layout, keypoints.fps,
                                 smooth_2d=args.smooth_2d, smooth_3d=args.smooth_3d, flip_test=args.flip_test)
    write_world(args.out, results, camera, args.checkpoint, overwrite=args.force)
    frames = sum(len(r.joints) for r in results.values())
    filled = sum(int(r.interpolated.sum()) for r in results.values())
    print(f"lifted {len(results)} track(s), {frames} frames ({keypoints.layout}, {keypoints.source}) with "
          f"{args.checkpoint} through camera {camera.name or args.camera} -> {args.out} (metres, z up)")
    if filled:
        print(f"note: {filled} missing input joint(s) were interpolated in time (listed in the output)")
    return 0


def _viz(args: argparse.Namespace) -> int:
    import numpy as np

    from ray3d.io.camera_files import read_camera
    from ray3d.io.exports import read_world
    from ray3d.viz.animation import render_frames, save_animation
    from ray3d.viz.html_viewer import write_viewer

    if not args.html and not args.animation:
        raise InputError("viz: nothing to write: pass --html and/or --animation")
    sequences = {}
    for path in args.world:
        world = read_world(path)
        track = args.track if args.track is not None else str(world["tracks"][0])
        rows = np.asarray(world["tracks"]).astype(str) == track
        if not rows.any():
            raise InputError(f"{path}: no track {track!r}")
        sequences[path.stem] = np.asarray(world["joints"], dtype=np.float64)[rows]
    fps = args.fps or 60.0
    camera = read_camera(args.camera) if args.camera else None
    if args.html:
        write_viewer(args.html, sequences, fps, camera, overwrite=args.force)
        print(f"wrote {args.html}")
    if args.animation:
        if camera is None:
            raise InputError("viz: --animation draws the 2D view and the camera: pass --camera")
        first = next(iter(sequences.values()))
        pixels = camera.project(first)
        images = render_frames(pixels, first, camera, stride=args.stride)
        save_animation(images, args.animation, fps / args.stride, overwrite=args.force)
        print(f"wrote {args.animation}")
    return 0


def _bench_robustness(args: argparse.Namespace) -> int:
    import numpy as np

    from ray3d.bench.robustness import run, write
    from ray3d.data import motion as motion_data

    clips = motion_data.load_shipped(args.data_dir, "test")
    if args.clips:
        clips = clips.select(np.arange(clips.num_clips) < args.clips)
    sweeps = run(args.models, clips, args.frame_stride, args.camera_stride)
    files = write(sweeps, args.out)
    print(f"{len(sweeps)} sweeps x {len(args.models)} methods on {clips.num_clips} test clips -> {len(files)} files "
          f"in {args.out} (see {args.out / 'summary.md'})")
    return 0


def _bench_calibration(args: argparse.Namespace) -> int:
    from ray3d.bench.calibration import run, write
    from ray3d.data import motion as motion_data
    from ray3d.lift import Lifter

    rows = run(motion_data.load_shipped(args.data_dir, args.split), Lifter.load(args.checkpoint), args.pairs, args.seed,
               args.bootstrap)
    files = write(rows, args.out)
    print((args.out / "calibration.md").read_text())
    print(f"{len(rows)} estimates -> {', '.join(map(str, files))}")
    return 0


def _bench_speed(args: argparse.Namespace) -> int:
    import json

    from ray3d.bench.speed import measure_all
    from ray3d.io.atomic import atomic_path

    result = measure_all(args.models, args.repeats, batch_size=args.batch, sequence_frames=args.sequence_frames,
                         train_batch=args.train_batch)
    paths = result["matmul_paths_gflops"]
    by_path = ", ".join(f"{name.removesuffix('_gflops')} {rate:.0f}" for name, rate in paths.items())
    print(f"fp32 matmul peak: {result['matmul_peak_gflops']:.0f} GFLOP/s ({by_path}); torch threads "
          f"{result['torch_threads']}")
    print(f"{'model':<15}{'backend':<13}{'params':>12}{'MFLOP/f':>9}{'batch f/s':>11}{'seq f/s':>10}"
          f"{'latency ms':>11}{'stream ms':>10}{'train s/s':>10}{'% peak':>8}")
    for r in result["models"]:
        train = f"{r['train_samples_per_s']:>10,.0f}" if r["train_samples_per_s"] else f"{'-':>10}"
        print(f"{r['model']:<15}{r['backend']:<13}{r['params']:>12,}{r['mflops_per_frame']:>9.2f}"
              f"{r['batch_frames_per_s']:>11,.0f}{r['sequence_frames_per_s']:>10,.0f}{r['latency_ms']:>11.2f}"
              f"{r['stream_ms_per_frame']:>10.2f}{train}"
              f"{100 * r['fraction_of_peak']:>8.1f}")
    if args.json:
        with atomic_path(args.json, overwrite=args.force) as temporary:
            temporary.write_text(json.dumps(result, indent=1))
        print(f"wrote {args.json}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    from ray3d.data.virtual_cameras import SET_NAMES

    parser = argparse.ArgumentParser(
        prog="ray3d", description="Absolute 3D human pose in world coordinates from one calibrated camera.")
    parser.add_argument("--version", action="version", version=f"ray3d {ray3d.__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    demo = commands.add_parser("demo", help="the main job: lift a bundled clip, compare with the truth and "
                                            "the baselines, write an HTML viewer and a GIF")
    demo.add_argument("--out", type=Path, default=Path("ray3d-demo"), help="output folder (default ray3d-demo)")
    demo.add_argument("--checkpoint", default="ray3d", help="model to demonstrate (default: the shipped Ray3D)")
    demo.add_argument("--frames", type=int, help="use only the first N frames")
    demo.set_defaults(handler=_demo)

    data = commands.add_parser("data", help="motion data: info, importers, virtual camera sets")
    data_commands = data.add_subparsers(dest="data_command", metavar="DATA_COMMAND", required=True)
    data_dir_help = "folder with cmu_h36m17.npz / hdm05_h36m17.npz (default: $RAY3D_DATA_DIR or ../shared/data/mocap)"

    info = data_commands.add_parser("info", help="what motion data is available: clips, frames, minutes, splits")
    info.add_argument("--data-dir", help=data_dir_help)
    info.set_defaults(handler=_data_info)

    bvh = data_commands.add_parser("import-bvh", help="BVH takes -> a motion npz (H36M-17, metres, z up)")
    bvh.add_argument("files", nargs="+", type=Path, metavar="FILE")
    bvh.add_argument("--units", choices=["m", "cm", "mm", "inch", "cmu"],
                     help="file length units (default: CMU units for cgspeed namings, cm for Daz)")
    _import_common(bvh)
    bvh.set_defaults(handler=_import_bvh)

    amc = data_commands.add_parser("import-amc", help="an ASF skeleton and AMC takes -> a motion npz")
    amc.add_argument("asf", type=Path, metavar="ASF")
    amc.add_argument("amc", nargs="+", type=Path, metavar="AMC")
    amc.add_argument("--native-fps", type=float, default=120.0, help="the AMC files' frame rate (default 120)")
    _import_common(amc)
    amc.set_defaults(handler=_import_amc)

    cams = data_commands.add_parser("cameras", help="write a named virtual camera set as JSON")
    cams.add_argument("--set", required=True, choices=SET_NAMES)
    cams.add_argument("--out", required=True, type=Path)
    cams.add_argument("--split", default="test", choices=["train", "validation", "test", "all"],
                      help="clips the cameras must see entirely (default: test)")
    cams.add_argument("--no-filter", action="store_true", help="write the whole grid, without the in-image filter")
    cams.add_argument("--data-dir", help=data_dir_help)
    cams.add_argument("--force", action="store_true", help="replace OUT if it exists")
    cams.set_defaults(handler=_cameras)

    train = commands.add_parser("train", help="train a model on the training performers with random cameras")
    train.add_argument("--config", type=Path, help="training config JSON (see configs/); default: Ray3D lite")
    train.add_argument("--preset", help="model preset replacing the config's model (ray3d, videopose3d, rie, ...)")
    train.add_argument("--out", required=True, type=Path, help="run folder: best.*, last.*, config.json")
    train.add_argument("--resume", action="store_true", help="continue the run in --out from its last epoch")
    train.add_argument("--epochs", type=int)
    train.add_argument("--batches-per-epoch", type=int)
    train.add_argument("--batch-size", type=int)
    train.add_argument("--seed", type=int)
    train.add_argument("--threads", type=int, help="torch CPU threads per process")
    train.add_argument("--data-dir", help=data_dir_help)
    train.add_argument("--quiet", action="store_true", help="no progress bar or per-epoch lines")
    train.set_defaults(handler=_train)

    evaluation = commands.add_parser("evaluate", help="MPJPE, P-MPJPE, Abs-MPJPE, MRPE of a model on mocap clips")
    evaluation.add_argument("--checkpoint", default="ray3d",
                            help="a checkpoint path or a shipped model name (ray3d, videopose3d, rie, ...) or rfrh")
    evaluation.add_argument("--mocap", type=Path, help="a motion npz (default: the shipped mocap's test performers)")
    evaluation.add_argument("--split", choices=["train", "validation", "test", "all"],
                            help="clips to use (default: test for the shipped files, all for any other npz)")
    evaluation.add_argument("--cameras", required=True, help=f"a camera set ({', '.join(SET_NAMES)}) or a cameras JSON")
    evaluation.add_argument("--datasets", help="with the shipped mocap: cmu, hdm05 or cmu,hdm05 (default both)")
    evaluation.add_argument("--joints", choices=["h36m17", "h36m14"], default="h36m17",
                            help="joints scored (h36m14: without spine, thorax and neck/nose)")
    evaluation.add_argument("--noise-px", type=float, default=0.0,
                            help="Gaussian noise on the 2D input, standard deviation in pixels (a detector's jitter)")
    evaluation.add_argument("--flip-test", action="store_true", help="average with the mirrored input's prediction")
    evaluation.add_argument("--frame-stride", type=int, default=1, help="evaluate every N-th frame (default 1)")
    evaluation.add_argument("--json", type=Path, help="write the results here")
    evaluation.add_argument("--force", action="store_true", help="replace --json if it exists")
    evaluation.add_argument("--data-dir", help=data_dir_help)
    evaluation.set_defaults(handler=_evaluate)

    lift = commands.add_parser("lift", help="2D keypoints + a calibrated camera -> 3D joints in world metres")
    lift.add_argument("--keypoints", required=True, type=Path,
                      help="npz / JSON / CSV (ours), COCO results JSON, an OpenPose folder, or VideoPose3D positions_2d npz")
    _add_camera_arguments(lift)
    lift.add_argument("--out", required=True, type=Path, help="output .json, .csv or .npz")
    lift.add_argument("--layout", help="joint layout of the keypoints (h36m17, coco17, blazepose33, body25, ...)")
    lift.add_argument("--fps", type=float, help="frame rate of the keypoints (default: from the file, else 60)")
    _add_lifting_arguments(lift)
    lift.add_argument("--subject", help="VideoPose3D npz: the subject")
    lift.add_argument("--action", help="VideoPose3D npz: the action")
    lift.add_argument("--camera-index", type=int, help="VideoPose3D npz: the camera index (0-3)")
    lift.add_argument("--force", action="store_true", help="replace --out if it exists")
    lift.set_defaults(handler=_lift)

    video = commands.add_parser("video", help="a video -> 2D detections -> world 3D, viewer and overlay video "
                                              "(pip install 'ray3d[video]')")
    video.add_argument("input", type=Path, help="the video file (anything OpenCV reads: .mp4, .avi, ...)")
    _add_camera_arguments(video, image_size_note=" (default: the video's)")
    video.add_argument("--out", required=True, type=Path, help="folder for world.*, keypoints.json, viewer.html, "
                                                                "overlay.mp4")
    video.add_argument("--detector", default="mediapipe", help="2D detector (default mediapipe)")
    video.add_argument("--format", choices=[".json", ".csv", ".npz"], default=".json", help="world file format")
    video.add_argument("--fps", type=float, help="override the frame rate the video reports")
    video.add_argument("--no-overlay", action="store_true", help="skip the overlay video")
    _add_lifting_arguments(video)
    video.add_argument("--force", action="store_true", help="replace existing outputs in --out")
    video.set_defaults(handler=_video)

    viz = commands.add_parser("viz", help="an HTML viewer and/or a GIF/MP4 of lifted 3D (outputs of ray3d lift)")
    viz.add_argument("world", nargs="+", type=Path, help="world outputs of ray3d lift (.json/.csv/.npz): one per method")
    viz.add_argument("--camera", help="the camera (drawn as a frustum; needed for --animation)")
    viz.add_argument("--html", type=Path, help="write the interactive viewer here")
    viz.add_argument("--animation", type=Path, help="write a .gif (or .mp4 with ffmpeg) here")
    viz.add_argument("--track", help="which track to show (default: the first)")
    viz.add_argument("--fps", type=float, help="playback frame rate (default 60)")
    viz.add_argument("--stride", type=int, default=2, help="animation: every N-th frame (default 2)")
    viz.add_argument("--force", action="store_true", help="replace existing outputs")
    viz.set_defaults(handler=_viz)

    bench = commands.add_parser("bench", help="benchmarks: robustness sweeps, speed")
    bench_commands = bench.add_subparsers(dest="bench_command", metavar="BENCH_COMMAND", required=True)
    robustness = bench_commands.add_parser("robustness", help="the paper's robustness sweeps (CSV, markdown, PNG)")
    robustness.add_argument("--out", required=True, type=Path, help="folder for the sweep files")
    robustness.add_argument("--models", nargs="+", default=["ray3d", "videopose3d", "rie", "rfrh"],
                            help="shipped names, checkpoint paths or rfrh, optionally LABEL=MODEL (default: the "
                                 "shipped ones and rfrh)")
    robustness.add_argument("--frame-stride", type=int, default=4, help="score every N-th frame (default 4)")
    robustness.add_argument("--camera-stride", type=int, default=1, help="use every N-th camera of each set")
    robustness.add_argument("--clips", type=int, help="use only the first N test clips (quick runs)")
    robustness.add_argument("--data-dir", help=data_dir_help)
    robustness.set_defaults(handler=_bench_robustness)
    calibration = bench_commands.add_parser("calibration", help="camera estimation from a walking person: errors "
                                                                "and their cost to Ray3D (CSV, JSON, markdown)")
    calibration.add_argument("--out", required=True, type=Path, help="folder for calibration.{csv,json,md}")
    calibration.add_argument("--pairs", type=int, default=12, help="random (camera, walking clip) pairs")
    calibration.add_argument("--bootstrap", type=int, default=30, help="bootstrap resamples per estimate")
    calibration.add_argument("--checkpoint", default="ray3d", help="the model that lifts (default ray3d)")
    calibration.add_argument("--seed", type=int, default=0)
    calibration.add_argument("--split", choices=["train", "validation", "test"], default="test",
                             help="whose walking clips (default: the test performers)")
    calibration.add_argument("--data-dir", help=data_dir_help)
    calibration.set_defaults(handler=_bench_calibration)
    speed_bench = bench_commands.add_parser("speed", help="inference and training speed of every model preset")
    speed_bench.add_argument("--json", type=Path, help="write the results here")
    speed_bench.add_argument("--models", nargs="+", help="presets to measure (default: all)")
    speed_bench.add_argument("--repeats", type=int, default=5)
    speed_bench.add_argument("--batch", type=int, default=1024, help="windows per inference batch")
    speed_bench.add_argument("--sequence-frames", type=int, default=10_000)
    speed_bench.add_argument("--train-batch", type=int, default=1024)
    speed_bench.add_argument("--force", action="store_true", help="replace --json if it exists")
    speed_bench.set_defaults(handler=_bench_speed)

    calibrate = commands.add_parser("calibrate", help="a camera from floor points with known positions, or from a "
                                                      "person walking on the floor")
    calibrate.add_argument("--floor-points", type=Path,
                           help="CSV (x,y,u,v) or JSON list: floor positions in metres and their pixels, 4 or more")
    calibrate.add_argument("--from-person", type=Path, metavar="KEYPOINTS",
                           help="instead of --floor-points: 2D keypoints of one person standing or walking on the "
                                "floor (any format ray3d lift reads); estimates height, pitch, roll (and focal)")
    calibrate.add_argument("--person-height", type=float, default=1.70,
                           help="with --from-person: the person's stature in metres (default 1.70)")
    calibrate.add_argument("--track", help="with --from-person: which track (default: the longest)")
    calibrate.add_argument("--layout", help="with --from-person: joint layout of the keypoints")
    calibrate.add_argument("--intrinsics", help="a camera file whose intrinsics (and distortion) to keep")
    _add_lens_arguments(calibrate, "instead of --intrinsics (with --from-person: --focal/--hfov if known)")
    calibrate.add_argument("--out", required=True, type=Path, help="camera JSON to write")
    calibrate.add_argument("--force", action="store_true", help="replace --out if it exists")
    calibrate.set_defaults(handler=_calibrate)

    models = commands.add_parser("models", help="the model presets: size, FLOPs per frame, which are shipped")
    models.set_defaults(handler=_models)

    exporting = commands.add_parser("export", help="a trained checkpoint -> inference weights (.safetensors + .json)")
    exporting.add_argument("--checkpoint", default="ray3d", help="a shipped model name or e.g. runs/NAME/best.safetensors")
    exporting.add_argument("--out", required=True, type=Path, help="target .safetensors (its .json is written beside)")
    exporting.add_argument("--onnx", action="store_true", help="write ONNX to --out instead (pip install 'ray3d[onnx]')")
    exporting.add_argument("--image-width", type=float, default=1000.0,
                           help="with --onnx: the image width pixel-input models normalise by (default 1000)")
    exporting.add_argument("--command-line", help="the training command, recorded with the weights")
    exporting.add_argument("--time-s", type=float, help="training wall time, recorded with the weights")
    exporting.add_argument("--machine", help="where it was trained, recorded with the weights")
    exporting.add_argument("--force", action="store_true", help="replace --out if it exists")
    exporting.set_defaults(handler=_export)

    speed = data_commands.add_parser("samples-speed", help="measure the training-sample generator's throughput")
    speed.add_argument("--batch", type=int, default=1024)
    speed.add_argument("--frames", type=int, default=9)
    speed.add_argument("--repeats", type=int, default=20)
    speed.add_argument("--data-dir", help=data_dir_help)
    speed.set_defaults(handler=_samples_speed)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        return args.handler(args)
    except InputError as err:
        print(f"ray3d {args.command}: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
