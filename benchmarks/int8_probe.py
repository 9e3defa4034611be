"""A first probe for reduced precision (issue 35): torch's dynamic int8 quantization of every ``nn.Linear`` of a
shipped model (the per-group layers the batched path runs at 128 windows and more) against fp32, on the bundled demo
clip repeated (4,840 frames) through its Human3.6M camera: frames/s of each, alternated, and how far the outputs
and their Abs-MPJPE move. Not a product path: torch 2.13 warns its quantized tensors are deprecated. With
``--onnx``, ONNX Runtime's dynamic int8 quantization of the exported model against ONNX Runtime fp32 instead.

    .venv/bin/python benchmarks/int8_probe.py [--model ray3d] [--repeats 2] [--onnx]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from ray3d import cameras
from ray3d.demo import DEMO_CAMERA, demo_clip
from ray3d.lift import Lifter


def _onnx_int8(lifter: Lifter, name: str) -> None:
    """``lifter``'s ONNX Runtime session replaced by one of the same model quantized to int8 (dynamic)."""
    import tempfile
    from pathlib import Path

    import onnxruntime
    from onnxruntime.quantization import QuantType, quantize_dynamic

    from ray3d.models import backends

    folder = Path(tempfile.mkdtemp())
    backends.export_onnx(Lifter.load(name).model, folder / "fp32.onnx")
    quantize_dynamic(str(folder / "fp32.onnx"), str(folder / "int8.onnx"), weight_type=QuantType.QInt8)
    lifter.model.session = onnxruntime.InferenceSession(str(folder / "int8.onnx"), onnxruntime.SessionOptions(),
                                                        providers=["CPUExecutionProvider"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", default="ray3d")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--onnx", action="store_true")
    args = parser.parse_args()
    camera = cameras.h36m(*DEMO_CAMERA)
    truth = np.concatenate([demo_clip()] * 20)
    pixels = camera.project(truth)
    if args.onnx:
        full, reduced = Lifter.load(args.model, backend="onnx"), Lifter.load(args.model, backend="onnx")
        _onnx_int8(reduced, args.model)
    else:
        full, reduced = Lifter.load(args.model), Lifter.load(args.model)
        torch.ao.quantization.quantize_dynamic(reduced.model, {torch.nn.Linear}, dtype=torch.qint8, inplace=True)
    for _ in range(args.repeats):
        timed = []
        for lifter in (full, reduced):
            started = time.perf_counter()
            joints = lifter.lift(pixels, camera, refine=False).joints
            timed.append((time.perf_counter() - started, joints))
        (t_full, j_full), (t_int8, j_int8) = timed
        error = [1000 * np.linalg.norm(j - truth, axis=-1).mean() for j in (j_full, j_int8)]
        print(f"{args.model}{' (ONNX Runtime)' if args.onnx else ''}: fp32 {len(pixels) / t_full:.0f} frames/s, int8 {len(pixels) / t_int8:.0f} frames/s "
              f"(x{t_full / t_int8:.2f}); outputs {1000 * np.linalg.norm(j_full - j_int8, axis=-1).mean():.1f} mm "
              f"apart; Abs-MPJPE {error[0]:.1f} -> {error[1]:.1f} mm")


if __name__ == "__main__":
    main()
