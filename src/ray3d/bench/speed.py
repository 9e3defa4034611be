"""Speed of every model on this machine: parameters, FLOPs per frame, batched and whole-sequence inference
throughput, single-window latency, live-mode latency per frame (``LiftStream.push``), training samples/s (the
step alone, and with the sample generator in the loop), which GEMM kernels each layer type runs, and the
``ray3d video`` rate when a video is given. Beside them the machine's own limits, measured in the same run: the
fp32 matmul peak (through ``nn.Linear`` / MKL, a 1x1 ``conv1d`` / oneDNN and, with the onnx extra, ONNX Runtime's
MatMul) and the memory bandwidth, and per model the bounds they set: frames/s and training samples/s at the
peak, and the single-window latency of reading every weight once. Medians over repetitions after warm-up; the
peak is the best repetition of the best shape."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from ray3d.models import PRESETS, LiftingNetwork
from ray3d.models.inference import inference_network
from ray3d.models.network import count_parameters, flops_per_frame, lifting_loss
from ray3d.models.tensor_batch import TensorBatch


# Where each backend's matrix products run: every layer of our networks, the temporal convolutions included
# (``FrameGroupLinear``), is a Linear, so torch takes the nn.Linear path of the GEMM probe.
GEMM_PATHS = {"torch": "linear", "torchscript": "linear", "onnxruntime": "onnxruntime"}


def repetition_seconds(function: Callable[[], object], repeats: int, warmup: int = 2) -> np.ndarray:
    """Wall time of each of ``repeats`` calls after ``warmup`` untimed ones."""
    for _ in range(warmup):
        function()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return np.array(times)


def median_seconds(function: Callable[[], object], repeats: int, warmup: int = 2) -> float:
    return float(np.median(repetition_seconds(function, repeats, warmup)))


@torch.no_grad()
def matmul_peak_gflops(shapes: tuple[tuple[int, int], ...] = ((1024, 8192), (2048, 8192)),
                       repeats: int = 10) -> dict[str, float]:
    """The best fp32 GEMM rate of (batch x size) @ (size x size) products over ``shapes`` ((size, batch)
    pairs), per path: nn.Linear, a 1x1 conv1d over a (1, size, batch) layout, and ONNX Runtime's MatMul."""
    rates: dict[str, float] = {}
    for size, batch in shapes:
        linear = torch.nn.Linear(size, size, bias=False)
        conv = torch.nn.Conv1d(size, size, 1, bias=False)
        x = torch.randn(batch, size)
        x_conv = x.T.unsqueeze(0).contiguous()  # (1, C, B): the batch as the conv's length
        flops = 2.0 * batch * size * size
        runs = {"linear_gflops": lambda: linear(x), "conv1d_gflops": lambda: conv(x_conv)}
        onnx_matmul = _onnx_runner(linear, x)
        if onnx_matmul is not None:
            runs["onnxruntime_gflops"] = onnx_matmul
        for path, run in runs.items():
            rates[path] = max(rates.get(path, 0.0), flops / repetition_seconds(run, repeats).min() / 1e9)
    return rates


@torch.no_grad()
def memory_gbps(megabytes: int = 512, repeats: int = 10) -> float:
    """Read bandwidth from memory (GB/s): the median time to sum a float32 array far larger than the caches."""
    array = torch.ones(megabytes * 2**20 // 4)
    return array.numel() * 4 / 1e9 / float(np.median(repetition_seconds(array.sum, repeats)))


def bounds(params: int, flops: float, peak_gflops: float, bandwidth_gbps: float) -> dict[str, float]:
    """What the machine allows a model: batched frames/s and training samples/s (a step is about 3x the forward
    FLOPs) at the matmul peak, and the latency of one window if it did nothing but read its fp32 weights once."""
    return {"bound_batch_frames_per_s": peak_gflops * 1e9 / flops,
            "bound_train_samples_per_s": peak_gflops * 1e9 / (3 * flops),
            "bound_latency_ms": 1e3 * params * 4 / (bandwidth_gbps * 1e9)}


_MATMUL_OPS = frozenset({"mm", "addmm", "bmm", "baddbmm", "addmv", "mv", "mkldnn_linear", "convolution",
                         "_mkldnn_convolution", "_native_multi_head_attention",
                         "_scaled_dot_product_flash_attention_for_cpu"})


def blas_library() -> str:
    """The BLAS torch was built with (its build configuration's BLAS_INFO), which runs aten::mm and friends."""
    for line in torch.__config__.show().splitlines():
        if "BLAS_INFO=" in line:
            return line.split("BLAS_INFO=")[1].split(",")[0].strip()
    return "unknown"


@torch.no_grad()
def layer_gemm_paths(model: torch.nn.Module, batch) -> dict[str, list[str]]:
    """{layer type: the matrix-product kernels (aten operators) its forward ran}, over one forward of ``model``
    on ``batch``; a kernel counts for the innermost module that called it."""
    from torch.utils._python_dispatch import TorchDispatchMode

    layers: list[str] = []
    paths: dict[str, set[str]] = {}

    class Recorder(TorchDispatchMode):
        def __torch_dispatch__(self, func, types, args=(), kwargs=None):
            name = func.overloadpacket.__name__
            if name in _MATMUL_OPS and layers:
                paths.setdefault(layers[-1], set()).add(f"aten::{name}")
            return func(*args, **(kwargs or {}))

    def enter(module, _inputs) -> None:
        layers.append(type(module).__name__)

    def leave(_module, _inputs, _output) -> None:  # returning None keeps the module's output
        layers.pop()

    handles = [h for m in model.modules() for h in (m.register_forward_pre_hook(enter), m.register_forward_hook(leave))]
    try:
        with Recorder():
            model(batch)
    finally:
        for handle in handles:
            handle.remove()
    return {layer: sorted(ops) for layer, ops in sorted(paths.items())}


def _onnx_runner(linear: torch.nn.Linear, x: torch.Tensor) -> Callable[[], object] | None:
    """``linear(x)`` through ONNX Runtime, or None without the onnx extra."""
    import io
    import warnings

    try:
        import onnxruntime
    except ImportError:
        return None
    buffer = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(linear, (x[:2],), buffer, input_names=["x"], dynamic_axes={"x": {0: "batch"}},
                          opset_version=17, dynamo=False)
    options = onnxruntime.SessionOptions()
    options.intra_op_num_threads = torch.get_num_threads()
    session = onnxruntime.InferenceSession(buffer.getvalue(), options, providers=["CPUExecutionProvider"])
    values = {"x": x.numpy()}
    return lambda: session.run(None, values)


def _batch(model: LiftingNetwork, size: int) -> TensorBatch:
    return TensorBatch.example(model.receptive_field, model.skeleton.num_joints, size)


def _inference_times(run, model: LiftingNetwork, repeats: int, batch_size: int, sequence_frames: int):
    """(batch seconds, single-window seconds, whole-sequence seconds) of ``run(TensorBatch)``."""
    batch, single, sequence = (_batch(model, n) for n in (batch_size, 1, sequence_frames))
    chunks = [TensorBatch(sequence.pixels[i:i + 4096], sequence.rays[i:i + 4096], sequence.camera_params[i:i + 4096],
                          sequence.intrinsics[i:i + 4096], sequence.roll[i:i + 4096], 1000.0)
              for i in range(0, sequence_frames, 4096)]
    with torch.no_grad():
        return (median_seconds(lambda: run(batch), repeats), median_seconds(lambda: run(single), max(repeats * 4, 20)),
                median_seconds(lambda: [run(c) for c in chunks], max(1, repeats // 2), warmup=0))  # warm already


def stream_ms_per_frame(runner, frames: int = 120) -> float:
    """Median wall time of one ``LiftStream.push`` (keypoints in, world joints out: rays, window, network and
    the way back to the world), the live-mode latency, over the bundled demo clip seen by an H36M camera."""
    from ray3d import cameras
    from ray3d.demo import demo_clip
    from ray3d.lift import Lifter

    camera = cameras.h36m("S9", "54138969")
    pixels = camera.project(demo_clip()[:frames])
    stream = Lifter(runner, {}).stream(camera)
    for keypoints in pixels[:20]:  # warm-up
        stream.push(keypoints)
    times = []
    for keypoints in pixels[20:]:
        start = time.perf_counter()
        stream.push(keypoints)
        times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times))


def measure_backend(name: str, backend: str, repeats: int = 5, batch_size: int = 1024,
                    sequence_frames: int = 10_000) -> dict | None:
    """The same inference figures through ``backend`` ("torchscript" or "onnxruntime"); None when ONNX Runtime
    is asked for and the onnx extra is not installed."""
    from ray3d.models.backends import OnnxLiftingModel, TorchScriptLiftingModel

    model = LiftingNetwork(PRESETS[name]).eval()
    if backend == "torchscript":
        runtime = TorchScriptLiftingModel(model)
    else:
        try:
            runtime = OnnxLiftingModel(model, threads=torch.get_num_threads())
        except Exception:  # the optional extra is missing: the other rows stand alone
            return None
    batch_s, latency_s, sequence_s = _inference_times(runtime, model, repeats, batch_size, sequence_frames)
    return {"model": name, "preset": "paper" if name.endswith("-paper") else "lite", "backend": backend,
            "gemm_path": GEMM_PATHS[backend],
            "params": count_parameters(model), "mflops_per_frame": flops_per_frame(model) / 1e6,
            "batch_frames_per_s": batch_size / batch_s, "sequence_frames_per_s": sequence_frames / sequence_s,
            "latency_ms": 1e3 * latency_s, "stream_ms_per_frame": stream_ms_per_frame(runtime),
            "train_samples_per_s": None}


def measure_model(name: str, repeats: int = 5, batch_size: int = 1024, sequence_frames: int = 10_000,
                  train_batch: int = 1024, peak_gflops: float | None = None, motion=None) -> dict:
    """The speed record of one preset (randomly initialised weights: speed does not depend on them).
    ``motion``: the training performers' mocap for the training loop's rate (loaded when not given)."""
    config = PRESETS[name]
    model = LiftingNetwork(config).eval()
    flops = flops_per_frame(model)
    lifted = inference_network(model)  # what ``Lifter`` runs
    batch_s, latency_s, sequence_s = _inference_times(lifted, model, repeats, batch_size, sequence_frames)
    # The same network as trained (batch norms, per-group layers), timed in the same run: the ratio is the claim.
    training_form_s = _inference_times(model, model, repeats, batch_size, sequence_frames)
    trainer = LiftingNetwork(config).train()
    from ray3d.train import TrainConfig, make_optimizer

    optimizer = make_optimizer(trainer, TrainConfig(model=config))  # the optimizer ``ray3d train`` uses
    train_input = _batch(trainer, train_batch)
    target_pose, target_root = torch.randn(train_batch, model.skeleton.num_joints, 3), torch.rand(train_batch, 3) + 2

    def step():
        pose, root = trainer(train_input)
        loss = lifting_loss(pose, root, target_pose, target_root)[0]
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()

    train_s = median_seconds(step, max(2, repeats // 2), warmup=1)
    loop_rate = train_loop_samples_per_s(config, train_batch, max(2, repeats // 2), motion)
    record = {
        "model": name, "preset": "paper" if name.endswith("-paper") else "lite", "backend": "torch",
        "gemm_path": GEMM_PATHS["torch"],
        "params": count_parameters(model), "mflops_per_frame": flops / 1e6,
        "batch_frames_per_s": batch_size / batch_s, "sequence_frames_per_s": sequence_frames / sequence_s,
        "latency_ms": 1e3 * latency_s, "stream_ms_per_frame": stream_ms_per_frame(lifted),
        "training_form": {"batch_frames_per_s": batch_size / training_form_s[0],
                          "latency_ms": 1e3 * training_form_s[1],
                          "sequence_frames_per_s": sequence_frames / training_form_s[2]},
        "train_samples_per_s": train_batch / train_s, "train_loop_samples_per_s": loop_rate,
        "layer_gemm_paths": layer_gemm_paths(lifted, _batch(model, 64)),
    }
    if peak_gflops:
        record["fraction_of_peak"] = record["batch_frames_per_s"] * flops / 1e9 / peak_gflops
    return record


def training_motion():
    """The shipped mocap's training performers, or None where it is not there."""
    from ray3d.data.motion import load_shipped
    from ray3d.errors import InputError

    try:
        return load_shipped(split="train")
    except InputError:
        return None


def train_loop_samples_per_s(config, batch_size: int, repeats: int, motion=None) -> float | None:
    """Training samples/s of ``ray3d train``'s loop itself (``train.training_steps``: the sample generator
    drawing each batch from the training performers' ``motion``, then the step); None without the mocap."""
    from ray3d.train import TrainConfig, training_steps

    motion = motion if motion is not None else training_motion()
    if motion is None:
        return None
    steps = training_steps(TrainConfig(model=config, batch_size=batch_size), motion)
    return batch_size / median_seconds(lambda: next(steps), repeats, warmup=1)


def measure_video(video, camera, frames: int = 100) -> dict:
    """``ray3d video``'s rate on the first ``frames`` frames of ``video`` seen by ``camera`` (its default
    detector and model, outputs to a temporary folder): frames/s of the people stage (reading, detecting,
    tracking), of lifting and writing, and end to end."""
    import tempfile

    from ray3d.options import VideoOptions
    from ray3d.video import DEFAULT_DETECTOR, lift_video, make_detector

    with tempfile.TemporaryDirectory() as out:
        result = lift_video(video, camera, Path(out) / "video", make_detector(DEFAULT_DETECTOR, camera),
                            video_options=VideoOptions(frames=frames), progress=False)
    seconds = result.seconds
    return {"video": str(video), "frames": result.frames, "people": len(result.world.tracks),
            "people_frames_per_s": result.frames / seconds["people"],
            "lifting_frames_per_s": result.frames / seconds["lifting"],
            "writing_frames_per_s": result.frames / seconds["writing"],
            "end_to_end_frames_per_s": result.frames / sum(seconds.values())}


def measure_all(models: list[str] | None = None, repeats: int = 5, video=None, camera=None, video_frames: int = 100,
                **sizes) -> dict:
    """Every figure for ``models`` (default: every preset), and ``ray3d video``'s rate when ``video`` and its
    ``camera`` are given."""
    peak = matmul_peak_gflops(repeats=2 * repeats)
    best = max(peak.values())
    bandwidth = memory_gbps()
    motion = training_motion()
    records = []
    for name in models or list(PRESETS):
        record = measure_model(name, repeats, peak_gflops=best, motion=motion, **sizes)
        record.update(bounds(record["params"], record["mflops_per_frame"] * 1e6, best, bandwidth))
        records.append(record)
        for backend in ("torchscript", "onnxruntime"):
            record = measure_backend(name, backend, repeats, sizes.get("batch_size", 1024),
                                     sizes.get("sequence_frames", 10_000))
            if record is not None:
                record["fraction_of_peak"] = record["batch_frames_per_s"] * record["mflops_per_frame"] * 1e6 / 1e9 / best
                records.append(record)
    return {"matmul_peak_gflops": best, "matmul_paths_gflops": peak, "memory_gbps": bandwidth,
            "blas": blas_library(), "torch_threads": torch.get_num_threads(), "models": records,
            "video": measure_video(video, camera, video_frames) if video is not None else None}


