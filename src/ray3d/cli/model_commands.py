"""``ray3d train``, ``evaluate``, ``export`` and ``models``: the models, trained, measured and shipped."""

from __future__ import annotations

import argparse
from pathlib import Path

from ray3d.cli.printing import write_json
from ray3d.io.atomic import check_output, refuse_existing


def train(args: argparse.Namespace) -> int:
    from ray3d.train import train as run
    from ray3d.train import training_config

    config = training_config(args.config, args.preset, epochs=args.epochs, batches_per_epoch=args.batches_per_epoch,
                             batch_size=args.batch_size, seed=args.seed, threads=args.threads, data_dir=args.data_dir)
    best = run(config, args.out, resume=args.resume, progress=not args.quiet)["best"]
    if best is None:  # a data-parallel worker other than rank 0: it neither validates nor reports
        return 0
    print(f"best epoch {best['epoch']}: validation Abs-MPJPE {best['abs_mpjpe_mm']:.1f} mm, MPJPE "
          f"{best['mpjpe_mm']:.1f} mm, MRPE {best['mrpe_mm']:.1f} mm -> {Path(args.out) / 'best.safetensors'}")
    return 0


def evaluate(args: argparse.Namespace) -> int:
    from ray3d.evaluate import METRICS, evaluation_cameras, evaluation_motion
    from ray3d.evaluate import evaluate as run

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
    write_json(args.json, result, args.force)
    return 0


def export(args: argparse.Namespace) -> int:
    from ray3d.checkpoints import export as copy_weights
    from ray3d.checkpoints import load_model

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
              f"{config.input:<15}{config.backbone:<12}{config.root:<12}"
              f"{'yes' if config.camera_embedding else 'no':<12}"
              f"{'yes' if name in shipped else 'no'}")
    print(f"\nshipped weights (Lifter.load(NAME), --checkpoint NAME): {', '.join(sorted(shipped))}; what each was "
          "trained on: src/ray3d/assets/models/MODELS.md")
    return 0
