"""The handlers of the ``ray3d`` subcommands: each turns its arguments into one library call and prints what
came back. Library modules are imported inside the handlers so that ``ray3d --help`` stays fast."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ray3d.errors import InputError


def _write_json(path: Path, document: dict, overwrite: bool) -> None:
    from ray3d.io.atomic import atomic_path

    with atomic_path(path, overwrite=overwrite) as temporary:
        temporary.write_text(json.dumps(document, indent=1))
    print(f"wrote {path}")


def demo(args: argparse.Namespace) -> int:
    from ray3d.demo import format_report, run_demo

    print(format_report(run_demo(args.out, args.checkpoint, frames=args.frames)))
    return 0


def data_info(args: argparse.Namespace) -> int:
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


def _write_imported(args: argparse.Namespace, clips, files: list[Path], source: str) -> int:
    from ray3d.data.importers import clips_to_motion_set

    motion = clips_to_motion_set(clips, [f.stem for f in files], args.subject, source)
    motion.save(args.out, overwrite=args.force)
    minutes = motion.num_frames / args.fps / 60
    print(f"wrote {args.out}: {motion.num_clips} clip(s), {motion.num_frames} frames ({minutes:.2f} min) at "
          f"{args.fps:g} fps; floor offsets {', '.join(f'{c.floor_offset_m:+.3f}' for c in clips)} m")
    return 0


def import_bvh(args: argparse.Namespace) -> int:
    from ray3d.data.importers import import_bvh as read

    clips = [read(f, args.fps, args.drop_frames, not args.no_floor, args.units) for f in args.files]
    return _write_imported(args, clips, args.files, "user_bvh")


def import_amc(args: argparse.Namespace) -> int:
    from ray3d.data.importers import import_amc as read

    clips = [read(args.asf, f, args.fps, args.native_fps, args.drop_frames, not args.no_floor) for f in args.amc]
    return _write_imported(args, clips, args.amc, "user_amc")


def cameras(args: argparse.Namespace) -> int:
    from ray3d.data import motion
    from ray3d.data.virtual_cameras import cameras_seeing, grid
    from ray3d.io.camera_files import save_cameras

    if args.no_filter:
        cams, note = grid(args.set), "not filtered"
    else:
        clips = motion.load_shipped(args.data_dir, args.split)
        cams = cameras_seeing(args.set, clips)
        note = f"kept cameras that see every joint of all {clips.num_clips} {args.split} clips (centred)"
    save_cameras(args.out, cams, overwrite=args.force, set=args.set, filter=note)
    print(f"wrote {args.out}: {len(cams)} of {len(grid(args.set))} '{args.set}' cameras ({note})")
    return 0


def samples_speed(args: argparse.Namespace) -> int:
    from ray3d.data import motion
    from ray3d.data.samples import THROUGHPUT_CASES, measure_throughput
    from ray3d.temporal import Window

    train = motion.load_shipped(args.data_dir, "train")
    print(f"training-sample generator: batch {args.batch} windows of {args.frames} frames, median of {args.repeats}")
    for name, config in THROUGHPUT_CASES.items():
        result = measure_throughput(train, config, Window(args.frames), args.batch, args.repeats)
        print(f"  {name:<36}{result['ms_per_batch']:8.1f} ms/batch{result['samples_per_s']:10,.0f} samples/s")
    return 0


def train(args: argparse.Namespace) -> int:
    from ray3d.train import train as run, training_config

    config = training_config(args.config, args.preset, epochs=args.epochs, batches_per_epoch=args.batches_per_epoch,
                             batch_size=args.batch_size, seed=args.seed, threads=args.threads, data_dir=args.data_dir)
    best = run(config, args.out, resume=args.resume, progress=not args.quiet)["best"]
    if best is None:  # a data-parallel worker other than rank 0: it neither validates nor reports
        return 0
    print(f"best epoch {best['epoch']}: validation Abs-MPJPE {best['abs_mpjpe_mm']:.1f} mm, MPJPE "
          f"{best['mpjpe_mm']:.1f} mm, MRPE {best['mrpe_mm']:.1f} mm -> {Path(args.out) / 'best.safetensors'}")
    return 0


def evaluate(args: argparse.Namespace) -> int:
    from ray3d.evaluate import METRICS, evaluate as run, evaluation_cameras, evaluation_motion

    datasets = tuple(args.datasets.split(",")) if args.datasets else None
    clips, source = evaluation_motion(args.mocap, args.split, datasets, args.data_dir)
    result = run(args.checkpoint, clips, evaluation_cameras(args.cameras), args.flip_test, args.frame_stride,
                 joints=args.joints, noise_px=args.noise_px, refine=args.refine)
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
        _write_json(args.json, result, args.force)
    return 0


def export(args: argparse.Namespace) -> int:
    from ray3d.checkpoints import export as copy_weights, load_model

    if args.onnx:
        from ray3d.io.atomic import atomic_path
        from ray3d.models.backends import export_onnx

        with atomic_path(args.out, overwrite=args.force) as temporary:
            export_onnx(load_model(args.checkpoint)[0], str(temporary), args.image_width)
        print(f"wrote {args.out} (ONNX, opset 17, inputs pixels/rays/camera_params/intrinsics/roll, batch axis dynamic)")
        return 0
    provenance = {"training": {"command": args.command_line, "time_s": args.time_s, "machine": args.machine}} \
        if args.command_line else {}
    target = copy_weights(args.checkpoint, args.out, overwrite=args.force, averaged=not args.last_weights,
                          **provenance)
    print(f"wrote {target} and {target.with_suffix('.json')}")
    return 0


def models(args: argparse.Namespace) -> int:
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
    print(f"\nshipped weights (Lifter.load(NAME), --checkpoint NAME): {', '.join(sorted(shipped))}; what each was "
          "trained on: src/ray3d/assets/models/MODELS.md")
    return 0


def _camera(args: argparse.Namespace):
    from ray3d.geometry import Camera
    from ray3d.io.camera_files import read_camera

    if args.camera:
        return read_camera(args.camera)
    if args.camera_height is None or args.pitch is None or args.image_size is None:
        raise InputError("pass --camera FILE, or --camera-height, --pitch, --image-size and --hfov or --focal")
    return Camera.from_height_pitch(args.camera_height, args.pitch, _image_size(args), args.roll, args.focal,
                                    args.hfov)


def _image_size(args: argparse.Namespace) -> tuple[int, int]:
    from ray3d.geometry import parse_image_size

    return parse_image_size(args.image_size, "--image-size")


def calibrate(args: argparse.Namespace) -> int:
    import numpy as np

    from ray3d.calibrate import from_floor_points
    from ray3d.geometry import pinhole_intrinsics
    from ray3d.io.camera_files import read_camera, save_cameras
    from ray3d.io.floor_points import read_floor_points

    if (args.floor_points is None) == (args.from_person is None):
        raise InputError("calibrate: pass exactly one of --floor-points FILE and --from-person KEYPOINTS")
    if args.from_person is not None:
        return _calibrate_from_person(args)
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
          f"{np.degrees(camera.roll):.2f} deg; reprojection RMS {rms:.2f} px over {len(pixels)} floor points -> {args.out}")
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
    track, _, pixels, confidences = keypoints.track(args.track)
    result = from_person(pixels, image_size, args.person_height, focal, keypoints.layout, confidences=confidences)
    save_cameras(args.out, [result.camera], overwrite=args.force, calibration="from person",
                 person_height_m=args.person_height, track=str(track), **result.to_dict())
    print(f"{result.summary()} (person {args.person_height:.2f} m tall, track {track}) -> {args.out}")
    return 0


def lift(args: argparse.Namespace) -> int:
    from ray3d.io.keypoints import read_keypoints
    from ray3d.io.world import write_world
    from ray3d.lift import Lifter

    if args.out.exists() and not args.force:
        raise InputError(f"{args.out}: already exists; refusing to overwrite it", arguments=("overwrite",))
    keypoints = read_keypoints(args.keypoints, args.layout, args.fps, subject=args.subject, action=args.action,
                               camera_index=args.camera_index)
    camera = _camera(args)
    if keypoints.fps is None:
        print(f"note: {args.keypoints} states no frame rate: assumed the models' 60 fps (pass --fps if it is "
              "another; speeds and smoothing depend on it)", file=sys.stderr)
    world = Lifter.load(args.checkpoint).lift_keypoints(keypoints, camera, smooth_2d=args.smooth_2d,
                                                        smooth_3d=args.smooth_3d, flip_test=args.flip_test,
                                                        refine=not args.no_refine)
    write_world(args.out, world, overwrite=args.force)
    frames = sum(len(r.joints) for r in world.tracks.values())
    filled = sum(int(r.interpolated.sum()) for r in world.tracks.values())
    print(f"lifted {len(world.tracks)} track(s), {frames} frames ({keypoints.layout}, {keypoints.source}) with "
          f"{args.checkpoint} through camera {camera.name or args.camera} -> {args.out} (metres, z up)")
    if filled:
        print(f"note: {filled} missing input joint(s) were interpolated in time (listed in the output)")
    _print_refinements(world.tracks)
    return 0


def _print_refinements(tracks: dict) -> None:
    for track, result in tracks.items():
        if result.refinement:
            r = result.refinement
            print(f"  track {track}: stature {r['stature_m']:.2f} m, moved x{r['median_scale']:.2f} along the rays, "
                  f"feet on the floor in {100 * r['contact_fraction']:.0f}% of frames, position +- "
                  f"{r['position_sd_m']:.2f} m")


def video(args: argparse.Namespace) -> int:
    from ray3d.lift import Lifter
    from ray3d.video import lift_video, make_detector, read_video_info

    info = read_video_info(args.input)
    if args.camera is None and args.image_size is None:
        args.image_size = f"{info.image_size[0]}x{info.image_size[1]}"
    result = lift_video(args.input, _camera(args), args.out, make_detector(args.detector), Lifter.load(args.checkpoint),
                        fps=args.fps, world_format=args.format, overlay=not args.no_overlay, overwrite=args.force,
                        smooth_2d=args.smooth_2d, smooth_3d=args.smooth_3d, flip_test=args.flip_test,
                        refine=not args.no_refine)
    found = int((result.confidences > 0).any(axis=1).sum())
    print(f"{args.input}: {len(result.keypoints)} frames, a person found in {found}; "
          f"{100 * result.lifted.missing_fraction:.1f}% of joints filled in from neighbouring frames")
    _print_refinements({"0": result.lifted})
    for role, path in result.files.items():
        print(f"  {role:<10}{path}")
    return 0


def viz(args: argparse.Namespace) -> int:
    from ray3d.io.camera_files import read_camera
    from ray3d.io.world import read_world
    from ray3d.viz.animation import render_frames, save_animation
    from ray3d.viz.html_viewer import write_viewer

    if not args.html and not args.animation:
        raise InputError("viz: nothing to write: pass --html and/or --animation")
    if args.animation and not args.camera:
        raise InputError("viz: --animation draws the 2D view and the camera: pass --camera")
    sequences = {path.stem: read_world(path).track(args.track).joints for path in args.world}
    fps = args.fps or 60.0
    camera = read_camera(args.camera) if args.camera else None
    if args.html:
        write_viewer(args.html, sequences, fps, camera, overwrite=args.force)
        print(f"wrote {args.html}")
    if args.animation:
        first = next(iter(sequences.values()))
        images = render_frames(camera.project(first), first, camera, stride=args.stride)
        save_animation(images, args.animation, fps / args.stride, overwrite=args.force)
        print(f"wrote {args.animation}")
    return 0


def bench_robustness(args: argparse.Namespace) -> int:
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


def bench_calibration(args: argparse.Namespace) -> int:
    from ray3d.bench.calibration import run, write
    from ray3d.data import motion as motion_data
    from ray3d.lift import Lifter

    rows = run(motion_data.load_shipped(args.data_dir, args.split), Lifter.load(args.checkpoint), args.pairs, args.seed,
               args.bootstrap)
    files = write(rows, args.out)
    print((args.out / "calibration.md").read_text())
    print(f"{len(rows)} estimates -> {', '.join(map(str, files))}")
    return 0


def bench_real_video(args: argparse.Namespace) -> int:
    from ray3d.bench.real_video import run_emulated, run_video, write
    from ray3d.data import motion as motion_data
    from ray3d.io.camera_files import read_camera
    from ray3d.io.keypoints import read_keypoints
    from ray3d.lift import Lifter

    lifter, video_rows, name = Lifter.load(args.checkpoint), None, ""
    if args.video or args.keypoints:
        if not args.camera:
            raise InputError("bench real-video: --video and --keypoints need --camera")
        if args.keypoints:
            keypoints, name = read_keypoints(args.keypoints, fps=args.fps), args.keypoints.name
        else:
            from ray3d.video import make_detector, video_keypoints

            keypoints, name = video_keypoints(args.video, make_detector(args.detector), args.fps), args.video.name
        video_rows = run_video(lifter, keypoints, read_camera(args.camera))
    emulated = run_emulated(lifter, motion_data.load_shipped(args.data_dir, "test"), args.pairs, args.seed)
    files = write(args.out, emulated, video_rows, name)
    print(files[1].read_text())
    print(f"-> {', '.join(map(str, files))}")
    return 0


def bench_speed(args: argparse.Namespace) -> int:
    from ray3d.bench.speed import measure_all

    result = measure_all(args.models, args.repeats, batch_size=args.batch, sequence_frames=args.sequence_frames,
                         train_batch=args.train_batch)
    by_path = ", ".join(f"{name.removesuffix('_gflops')} {rate:.0f}"
                        for name, rate in result["matmul_paths_gflops"].items())
    print(f"fp32 matmul peak: {result['matmul_peak_gflops']:.0f} GFLOP/s ({by_path}); torch threads "
          f"{result['torch_threads']}")
    print(f"{'model':<15}{'backend':<13}{'params':>12}{'MFLOP/f':>9}{'batch f/s':>11}{'seq f/s':>10}"
          f"{'latency ms':>11}{'stream ms':>10}{'train s/s':>10}{'% peak':>8}")
    for r in result["models"]:
        train_rate = f"{r['train_samples_per_s']:>10,.0f}" if r["train_samples_per_s"] else f"{'-':>10}"
        print(f"{r['model']:<15}{r['backend']:<13}{r['params']:>12,}{r['mflops_per_frame']:>9.2f}"
              f"{r['batch_frames_per_s']:>11,.0f}{r['sequence_frames_per_s']:>10,.0f}{r['latency_ms']:>11.2f}"
              f"{r['stream_ms_per_frame']:>10.2f}{train_rate}{100 * r['fraction_of_peak']:>8.1f}")
    if args.json:
        _write_json(args.json, result, args.force)
    return 0
