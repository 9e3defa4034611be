"""Speed of the models on this machine, every figure beside the machine's own bound measured in the same rounds.

What is timed, per model: batched inference (frames/s) and single-window latency of every form and backend (the
torch inference form in fp32, bf16 and int8 (``models.precision``), the network as trained, TorchScript, and ONNX
Runtime with the onnx extra), the live ``LiftStream.push``, and training (one step on a fixed batch, and ``ray3d
train``'s loop with the sample generator in it). What bounds them, timed in the same rounds: the matrix-product
peak in fp32, bf16 and int8 (the fastest of (8192 x 640) @ (640 x 640), (4096 x 1024) @ (1024 x 1024) and
(4096 x 2048) @ (2048 x 2048) products through ``nn.Linear``, and as ``models.precision`` runs its bf16 and int8
layers) and the memory read bandwidth. Each figure runs for about ``ROUND_SECONDS`` per round (as many calls as fit; the
mean for rates, the median for latencies).

Why rounds: on a shared 2-core machine the rate drifts by tens of percent over minutes, so one form timed after
another measured the order more than the form. Every figure is timed once per round, in an order rotated from
round to round, beside the bounds; each figure's fraction of its bound is taken within its round and the
median over rounds reported, with the spread (largest over smallest) of the figure over the rounds.
"""

from __future__ import annotations

import copy
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from ray3d.bench.machine import layer_gemm_paths, machine
from ray3d.models import PRESETS, LiftingNetwork
from ray3d.models.network import count_parameters, flops_per_frame, lifting_loss
from ray3d.models.precision import PRECISIONS, Bfloat16Products, Int8Products, with_precision
from ray3d.models.tensor_batch import TensorBatch

DEFAULT_MODELS = ("ray3d", "ray3d-paper")
PEAK_SHAPES = ((8192, 640), (4096, 1024), (4096, 2048))  # (rows, size): a round's peak is the fastest
ROUND_SECONDS = 0.25  # each figure's share of a round: enough calls of a short run to take this long
BYTES_PER_WEIGHT = {"fp32": 4, "bf16": 2, "int8": 1}


def interleaved(runs: dict[str, Callable[[], float]], rounds: int, warmup: int = 1) -> dict[str, np.ndarray]:
    """{name: (rounds,) values}: each run (returning what it measured, e.g. seconds) once per round, in an order
    rotated by one from round to round, after ``warmup`` untimed calls of each."""
    names = list(runs)
    for name in names:
        for _ in range(warmup):
            runs[name]()
    values: dict[str, list[float]] = {name: [] for name in names}
    for r in range(rounds):
        for name in names[r % len(names):] + names[:r % len(names)]:
            values[name].append(runs[name]())
    return {name: np.array(v) for name, v in values.items()}


def seconds_of(function: Callable[[], object]) -> Callable[[], float]:
    """A run that times one call of ``function``."""
    def run() -> float:
        start = time.perf_counter()
        function()
        return time.perf_counter() - start
    return run


def per_call_seconds_of(function: Callable[[], object], typical: str = "mean") -> Callable[[], float]:
    """A run that calls ``function`` for about ``ROUND_SECONDS`` (as many calls as its first, untimed call says
    fit) and gives the seconds per call: their mean (throughput) or their median (latency)."""
    calls: list[int] = []

    def run() -> float:
        if not calls:  # the first call (the warm-up) sizes the rest
            calls.append(max(1, round(ROUND_SECONDS / max(seconds_of(function)(), 1e-6))))
            return 0.0
        times = [seconds_of(function)() for _ in range(calls[0])]
        return float(np.mean(times) if typical == "mean" else np.median(times))
    return run


def peak_runs(precisions: tuple[str, ...] = PRECISIONS) -> dict[str, Callable[[], float]]:
    """{"peak_<precision>": run}: the matrix-product probe in each of ``precisions``, a hidden layer as
    ``models.precision`` runs it; each run gives the best rate (FLOP/s) of the ``PEAK_SHAPES`` in its round."""
    x = {size: torch.randn(rows, size) for rows, size in PEAK_SHAPES}
    runs = {}
    for precision in precisions:
        probes = []
        for rows, size in PEAK_SHAPES:
            linear = torch.nn.Linear(size, size, bias=False).eval()
            layer = {"fp32": linear, "bf16": Bfloat16Products(copy.deepcopy(linear)),
                     "int8": Int8Products(linear)}[precision]
            probes.append((2.0 * rows * size * size, per_call_seconds_of(torch.no_grad()(
                lambda layer=layer, x=x[size]: layer(x)))))
        runs[f"peak_{precision}"] = lambda probes=probes: max(flops / max(run(), 1e-12) for flops, run in probes)
    return runs


def memory_run(megabytes: int = 256) -> tuple[Callable[[], float], int]:
    """(a run that sums a float32 array far larger than the caches, the bytes it reads): the read bandwidth."""
    array = torch.ones(megabytes * 2**20 // 4)
    return per_call_seconds_of(array.sum, "median"), array.numel() * 4


def bounds(params: int, flops: float, peak_gflops: float, bandwidth_gbps: float) -> dict[str, float]:
    """What the machine allows a model: batched frames/s and training samples/s (a step is about 3x the forward
    FLOPs) at the matmul peak, and the latency of one window if it did nothing but read its fp32 weights once."""
    return {"bound_batch_frames_per_s": peak_gflops * 1e9 / flops,
            "bound_train_samples_per_s": peak_gflops * 1e9 / (3 * flops),
            "bound_latency_ms": 1e3 * params * 4 / (bandwidth_gbps * 1e9)}


def _batch(model: LiftingNetwork, size: int) -> TensorBatch:
    return TensorBatch.example(model.receptive_field, model.skeleton.num_joints, size)


def model_forms(name: str, backends: bool = True) -> dict[str, tuple[str, str, Callable]]:
    """{form: (backend, precision, runner)} of preset ``name`` (random weights: speed does not depend on them):
    the torch inference form in every precision, the network as trained, and with ``backends`` TorchScript and,
    when installed, ONNX Runtime."""
    from ray3d.models.backends import OnnxLiftingModel, TorchScriptLiftingModel

    model = LiftingNetwork(PRESETS[name]).eval()
    forms = {f"torch {p}": ("torch", p, with_precision(model, p)) for p in PRECISIONS}
    forms["torch as trained"] = ("torch", "fp32", model)
    if backends:
        forms["torchscript"] = ("torchscript", "fp32", TorchScriptLiftingModel(model))
        try:
            forms["onnxruntime"] = ("onnxruntime", "fp32", OnnxLiftingModel(model, threads=torch.get_num_threads()))
        except Exception:  # the onnx extra is not installed: the other forms stand alone
            pass
    return forms


def _fraction(numerator: np.ndarray, denominator: np.ndarray) -> float:
    return float(np.median(numerator / denominator))


def _spread(values: np.ndarray) -> float:
    return float(values.max() / values.min())


@torch.no_grad()
def measure_inference(name: str, rounds: int, batch_size: int = 1024, backends: bool = True) -> list[dict]:
    """One record per form of preset ``name``: batched frames/s and single-window latency, each timed in every
    round beside the matrix-product peaks and the memory bandwidth, with its fraction of its bound."""
    forms = model_forms(name, backends)
    model = forms["torch as trained"][2]
    params, flops = count_parameters(model), flops_per_frame(model)
    batch, single = _batch(model, batch_size), _batch(model, 1)
    runs = peak_runs()
    runs["memory"], memory_bytes = memory_run()
    for form, (_, _, runner) in forms.items():
        runs[f"{form} batch"] = per_call_seconds_of(lambda r=runner: r(batch))
        runs[f"{form} latency"] = per_call_seconds_of(lambda r=runner: r(single), "median")
    times = interleaved(runs, rounds)
    peak = {p: times[f"peak_{p}"] / 1e9 for p in PRECISIONS}  # GFLOP/s per round
    bandwidth = memory_bytes / times["memory"] / 1e9  # GB/s per round
    records = []
    for form, (backend, precision, _) in forms.items():
        rate = batch_size / times[f"{form} batch"]
        latency = times[f"{form} latency"]
        weight_bytes = params * BYTES_PER_WEIGHT[precision]
        records.append({
            "model": name, "preset": "paper" if name.endswith("-paper") else "lite", "form": form,
            "backend": backend, "precision": precision, "params": params, "mflops_per_frame": flops / 1e6,
            "batch_frames_per_s": float(np.median(rate)), "latency_ms": 1e3 * float(np.median(latency)),
            # fractions within each round: of the fp32 peak (the claim against fp32), of the form's own
            # precision's peak, and of reading the weights once at the round's bandwidth
            "batch_fraction_of_fp32_peak": _fraction(rate * flops / 1e9, peak["fp32"]),
            "batch_fraction_of_own_peak": _fraction(rate * flops / 1e9, peak[precision]),
            "latency_fraction_of_bound": _fraction(weight_bytes / (bandwidth * 1e9), latency),
            "spread": {"batch": _spread(rate), "latency": _spread(latency)},
        })
    fp32 = next(r for r in records if r["form"] == "torch fp32")
    for record in records:  # within-round ratios against the fp32 inference form, the precision claim
        record["batch_speedup_over_fp32"] = _fraction(times["torch fp32 batch"], times[f"{record['form']} batch"])
        record["latency_ratio_to_fp32"] = _fraction(times[f"{record['form']} latency"], times["torch fp32 latency"])
    fp32["peaks_gflops"] = {p: float(np.median(v)) for p, v in peak.items()}
    fp32["memory_gbps"] = float(np.median(bandwidth))
    fp32.update(bounds(params, flops, fp32["peaks_gflops"]["fp32"], fp32["memory_gbps"]))
    fp32["layer_gemm_paths"] = layer_gemm_paths(forms["torch fp32"][2], _batch(model, 64))
    return records


def measure_training(name: str, rounds: int, train_batch: int = 1024, motion=None) -> dict:
    """Training samples/s of preset ``name``: one step on a fixed batch, and ``ray3d train``'s loop (the sample
    generator in it; None without the mocap), each timed in every round beside the fp32 peak, with the
    fraction of the training bound (3x the forward FLOPs at that peak)."""
    from ray3d.train import TrainConfig, make_optimizer, training_steps

    config = PRESETS[name]
    trainer = LiftingNetwork(config).train()
    flops = flops_per_frame(trainer)
    optimizer = make_optimizer(trainer, TrainConfig(model=config))  # the optimizer ``ray3d train`` uses
    train_input = _batch(trainer, train_batch)
    target_pose, target_root = torch.randn(train_batch, trainer.skeleton.num_joints, 3), torch.rand(train_batch, 3) + 2

    def step():
        pose, root = trainer(train_input)
        loss = lifting_loss(pose, root, target_pose, target_root)[0]
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()

    runs = {**peak_runs(("fp32",)), "step": seconds_of(step)}
    motion = motion if motion is not None else training_motion()
    if motion is not None:
        steps = training_steps(TrainConfig(model=config, batch_size=train_batch), motion)
        runs["loop"] = seconds_of(lambda: next(steps))
    times = interleaved(runs, rounds)
    bound = times["peak_fp32"] / (3 * flops)  # samples/s per round
    record = {"model": name, "train_batch": train_batch, "bound_train_samples_per_s": float(np.median(bound))}
    for key in ("step", "loop"):
        rate = train_batch / times[key] if key in times else None
        record[f"train_{key}_samples_per_s"] = None if rate is None else float(np.median(rate))
        record[f"train_{key}_fraction_of_bound"] = None if rate is None else _fraction(rate, bound)
        record[f"train_{key}_spread"] = None if rate is None else _spread(rate)
    return record


def stream_ms_per_frame(runner, frames: int = 120) -> float:
    """Median wall time of one ``LiftStream.push`` (keypoints in, world joints out: rays, window, network and
    the way back to the world), the live-mode latency, over the bundled demo clip seen by an H36M camera."""
    from ray3d import cameras
    from ray3d.demo import demo_clip
    from ray3d.lifting.lifter import Lifter

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


def training_motion():
    """The shipped mocap's training performers, or None where it is not there."""
    from ray3d.data.motion import load_shipped
    from ray3d.errors import InputError

    try:
        return load_shipped(split="train")
    except InputError:
        return None


def measure_video(video, camera, frames: int = 100) -> dict:
    """``ray3d video``'s rate on the first ``frames`` frames of ``video`` seen by ``camera`` (its default
    detector and model, outputs to a temporary folder): frames/s of the people stage (reading, detecting,
    tracking), of lifting and writing, and end to end."""

    from ray3d.jobs import CameraChoice, Job, run_input
    from ray3d.lifting.options import VideoOptions

    job = Job((video,), (CameraChoice(made=camera),), video=VideoOptions(frames=frames))
    with tempfile.TemporaryDirectory() as out:
        result = run_input(job, 0, Path(out) / "video", progress=False)
    seconds = result.video.seconds
    return {"video": str(video), "frames": result.frames, "people": len(result.world.tracks),
            "people_frames_per_s": result.frames / seconds["people"],
            "lifting_frames_per_s": result.frames / seconds["lifting"],
            "writing_frames_per_s": result.frames / seconds["writing"],
            "end_to_end_frames_per_s": result.frames / sum(seconds.values())}


def measure_all(models: list[str] | None = None, rounds: int = 7, video=None, camera=None, video_frames: int = 100,
                batch_size: int = 1024, train_batch: int = 1024, backends: bool = True) -> dict:
    """Every figure for ``models`` (default ``DEFAULT_MODELS``; ``["all"]``: every preset), and ``ray3d
    video``'s rate when ``video`` and its ``camera`` are given."""
    names = list(PRESETS) if models == ["all"] else list(models or DEFAULT_MODELS)
    motion = training_motion()
    inference, training, streams = [], [], []
    for name in names:
        inference += measure_inference(name, rounds, batch_size, backends)
        training.append(measure_training(name, max(3, rounds // 2), train_batch, motion))
        streams.append(measure_streams(name))
    return {"machine": machine(), "rounds": rounds, "batch": batch_size, "inference": inference,
            "training": training, "streams": streams,
            "video": measure_video(video, camera, video_frames) if video is not None else None}


def measure_streams(name: str, rounds: int = 3) -> dict:
    """Live latency (ms per ``LiftStream.push``) of preset ``name`` per precision, interleaved over rounds."""
    model = LiftingNetwork(PRESETS[name]).eval()
    runs = {p: (lambda net=with_precision(model, p): stream_ms_per_frame(net)) for p in PRECISIONS}
    times = interleaved(runs, rounds, warmup=0)
    return {"model": name, **{f"stream_ms_{p}": float(np.median(v)) for p, v in times.items()}}
