"""The handlers of the ``ray3d`` subcommands: each turns its arguments into one library call and prints what
came back. Library modules are imported inside the handlers so that ``ray3d --help`` stays fast."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ray3d.body import PLAUSIBLE_STATURE_M
from ray3d.cli.arguments import job_from_args
from ray3d.errors import InputError
from ray3d.io.atomic import check_output, refuse_existing


def write_json(path: Path, document: dict, overwrite: bool) -> None:
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

    if args.json is not None:  # refused before any work, not after it
        refuse_existing(check_output(args.json), args.force)
    datasets = tuple(args.datasets.split(",")) if args.datasets else None
    clips, source = evaluation_motion(args.mocap, args.split, datasets, args.data_dir)
    cameras = evaluation_cameras(args.cameras)

    def measured(precision: str) -> dict:
        return run(args.checkpoint, clips, cameras, args.flip_test, args.frame_stride, joints=args.joints,
                   noise_px=args.noise_px, refine=args.refine, progress=True, precision=precision)

    result = {"model": args.checkpoint, "mocap": source, "cameras": args.cameras, "precision": args.precision,
              **measured(args.precision)}
    if args.precision != "fp32":  # what the reduced precision costs, on the same clips
        full = measured("fp32")
        result["change_from_fp32_mm"] = {k: result[k] - full[k] for k in METRICS if result[k] is not None}
    print(f"{args.checkpoint} on {source}, cameras {args.cameras}: {result['pairs']} (camera, clip) pairs, "
          f"{result['skipped_pairs']} skipped (not fully in view), {result['frames']:,} frames")
    header = "".join(f"{k.removesuffix('_mm'):>12}" for k in METRICS)
    print(f"{'camera':<36}{header}{'frames':>10}")

    def row(name: str, values: dict) -> str:
        cells = "".join(f"{values[k]:>12.1f}" if values[k] is not None else f"{'-':>12}" for k in METRICS)
        return f"{name:<36}{cells}{values['frames']:>10,}"

    for name, values in result["per_camera"].items():
        print(row(name, values))
    for name, values in result["per_posture"].items():
        print(row(f"posture: {name}", values))
    print(row("overall (mm)", result))
    if "change_from_fp32_mm" in result:
        print(f"{args.precision} against fp32 (mm, same clips and cameras): " + ", ".join(
            f"{k.removesuffix('_mm')} {v:+.2f}" for k, v in result["change_from_fp32_mm"].items()))
    if result.get("within_1sd") is not None:
        print(f"the true root within the reported sd along its ray: {100 * result['within_1sd']:.1f} % of frames "
              f"within 1 sd, {100 * result['within_2sd']:.1f} % within 2; across it: "
              f"{100 * result['across_within_1sd']:.1f} % / {100 * result['across_within_2sd']:.1f} %")
    if args.json:
        write_json(args.json, result, args.force)
    return 0


def export(args: argparse.Namespace) -> int:
    from ray3d.checkpoints import export as copy_weights, load_model

    if args.onnx:
        from ray3d.io.atomic import atomic_path
        from ray3d.models.backends import export_onnx

        with atomic_path(args.out, overwrite=args.force) as temporary:
            export_onnx(load_model(args.checkpoint)[0], str(temporary), args.image_width)
        print(f"wrote {args.out} (ONNX, opset 17, inputs pixels/rays/camera_params/intrinsics/roll, and confidences "
              "for models that read them; batch axis dynamic)")
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

    print(f"{'preset':<15}{'frames':>7}{'params':>12}{'MFLOPs/frame':>14}  {'input':<15}{'backbone':<12}{'root':<12}"
          f"{'camera emb.':<12}shipped")
    shipped = set(shipped_models())
    for name, config in PRESETS.items():
        model = LiftingNetwork(config)
        print(f"{name:<15}{config.frames:>7}{count_parameters(model):>12,}{flops_per_frame(model) / 1e6:>14.2f}  "
              f"{config.input:<15}{config.backbone:<12}{config.root:<12}{'yes' if config.camera_embedding else 'no':<12}"
              f"{'yes' if name in shipped else 'no'}")
    print(f"\nshipped weights (Lifter.load(NAME), --checkpoint NAME): {', '.join(sorted(shipped))}; what each was "
          "trained on: src/ray3d/assets/models/MODELS.md")
    return 0


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
    check_output(args.out, (args.floor_points, args.from_person, args.intrinsics))
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
    people = dict([keypoints.track(args.track)]) if args.track is not None else keypoints.by_track()  # or everybody
    confidences = [d.confidences for d in people.values()]
    result = from_person([d.pixels for d in people.values()], image_size, args.person_height, focal, keypoints.layout,
                         confidences=None if any(c is None for c in confidences) else confidences)
    save_cameras(args.out, [result.camera], overwrite=args.force, calibration="from person",
                 person_height_m=args.person_height, tracks=[str(t) for t in people], **result.to_dict())
    print(f"{result.summary()} (people {args.person_height:.2f} m tall on average) -> {args.out}")
    for warning in result.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    return 0


def lift(args: argparse.Namespace) -> int:
    """One keypoint file and its camera (``ray3d.cli.fusion_commands.lift`` hands several on to ``lift_several``)."""
    from ray3d.jobs import run_input

    check_output(args.out, (args.camera,))
    lifted = run_input(job_from_args(args, [args.keypoints], "keypoint files", "file"), 0, args.out)
    keypoints, world, camera = lifted.keypoints, lifted.world, lifted.camera
    if keypoints.fps is None:
        print(f"note: {args.keypoints} states no frame rate: assumed the models' 60 fps (pass --fps if it is "
              "another; speeds and smoothing depend on it)", file=sys.stderr)
    if keypoints.frame_order:
        print(f"note: {args.keypoints} names its frames by text: ordered {keypoints.frame_order}", file=sys.stderr)
    if keypoints.untracked_dropped:
        print(f"note: {args.keypoints} has several people in some frames but no track ids: lifted each frame's "
              f"most confident person, {keypoints.untracked_dropped} other detection(s) left out (give track ids, "
              "e.g. AlphaPose --pose_track, to lift everybody)", file=sys.stderr)
    frames = sum(len(r.joints) for r in world.tracks.values())
    filled = sum(int(r.interpolated.sum()) for r in world.tracks.values())
    written = ", ".join(str(p) for p in lifted.files.values())
    print(f"lifted {len(world.tracks)} track(s), {frames} frames ({keypoints.layout}, {keypoints.source}) with "
          f"{world.model} through camera {camera.name or args.camera} -> {written} (metres, {args.frame} frame)")
    if filled:
        print(f"note: {filled} missing input joint(s) were interpolated in time (listed in the output)")
    for track, why in world.unliftable.items():
        print(f"warning: track {track} was not lifted: {why}", file=sys.stderr)
    print_refinements(world.tracks, camera)
    return 0


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


def batch(args: argparse.Namespace) -> int:
    from ray3d.batch import run

    report = run(args.manifest, args.out, args.address, args.workers, args.retries, args.cpus_per_task,
                 args.gpus_per_task)
    counts = {status: sum(r.status == status for r in report.reports) for status in ("done", "skipped", "failed")}
    print(f"{len(report.reports)} inputs: {counts['done']} done, {counts['skipped']} skipped (up to date), "
          f"{counts['failed']} failed -> {args.out} (summary: {report.summary})")
    for failure in report.failed:
        print(f"  failed: {failure.name} ({failure.input}): {failure.error}", file=sys.stderr)
    if report.failed:
        print(f"error: {len(report.failed)} of {len(report.reports)} inputs failed", file=sys.stderr)
        return 1
    return 0


def viz(args: argparse.Namespace) -> int:
    from ray3d.io.camera_files import read_camera
    from ray3d.temporal import check_frame_rate
    from ray3d.io.world import read_world
    from tqdm import tqdm

    from ray3d.viz.animation import check_animation_path, frame_span, render_frames, save_animation
    from ray3d.viz.html_viewer import write_viewer

    if not args.html and not args.animation:
        raise InputError("viz: nothing to write: pass --html and/or --animation")
    for target in (args.html, args.animation):
        if target is not None:
            check_output(target, (*args.world, args.camera, args.keypoints))
    if args.animation is not None:
        check_animation_path(args.animation)
    worlds = [read_world(path).in_frame("world") for path in args.world]  # a camera-frame file too
    sequences = {}
    for path, world in zip(args.world, worlds):
        chosen = [args.track] if args.track is not None else list(world.tracks)
        for track in chosen:  # every track of every file; a file's stem names it when there are several files
            result = world.track(track)
            sequences[track if len(worlds) == 1 else f"{path.stem}:{track}"] = result
    fps = check_frame_rate(worlds[0].fps if args.fps is None else args.fps, "viz")
    camera = read_camera(args.camera) if args.camera else worlds[0].camera
    if args.html:
        write_viewer(args.html, sequences, fps, camera, overwrite=args.force,
                     more_cameras=() if args.camera else worlds[0].cameras[1:])
        print(f"wrote {args.html} ({len(sequences)} tracks, {fps:g} frames/s)")
    if args.animation:
        if args.stride < 1:
            raise InputError(f"viz: stride must be 1 or more, got {args.stride}", arguments=("stride",))
        inputs = None
        if args.keypoints is not None:
            from ray3d.io.keypoints import read_keypoints

            keypoints = read_keypoints(args.keypoints)
            inputs = {name: keypoints.h36m_pixels(name.split(":")[-1], result.frames)
                      for name, result in sequences.items()}
        first, last = frame_span(sequences)
        images = tqdm(render_frames(sequences, camera, inputs, stride=args.stride, fps=fps), desc="rendering",
                      unit="frame", total=(last - first) // args.stride + 1, leave=False)
        save_animation(images, args.animation, fps / args.stride, overwrite=args.force)
        print(f"wrote {args.animation}")
    return 0
