"""``ray3d bench speed`` end to end on a tiny configuration: well-formed JSON with the documented keys."""

from __future__ import annotations

import json

import pytest

from ray3d.cli import main

KEYS = {"model", "preset", "form", "backend", "precision", "params", "mflops_per_frame", "batch_frames_per_s",
        "latency_ms", "batch_fraction_of_fp32_peak", "batch_fraction_of_own_peak", "latency_fraction_of_bound",
        "spread", "batch_speedup_over_fp32", "latency_ratio_to_fp32"}
FP32_KEYS = {"peaks_gflops", "memory_gbps", "layer_gemm_paths", "bound_batch_frames_per_s", "bound_train_samples_per_s",
             "bound_latency_ms"}


def test_bench_speed_writes_the_documented_json(tmp_path, capsys):
    out = tmp_path / "speed.json"
    assert main(["bench", "speed", "--models", "videopose3d", "poselifter", "--rounds", "2", "--batch", "16",
                 "--train-batch", "16", "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["machine"]["cores"] >= 1 and result["machine"]["blas"] and result["rounds"] == 2
    forms = [(r["model"], r["form"]) for r in result["inference"]]
    for model in ("videopose3d", "poselifter"):  # every precision of the inference form, the trained form, a trace
        assert ({(model, f) for f in ("torch fp32", "torch bf16", "torch int8", "torch as trained", "torchscript")}
                <= set(forms))
    for record in result["inference"]:
        assert KEYS <= set(record)
        assert record["batch_frames_per_s"] > 0 and record["latency_ms"] > 0
        assert record["batch_fraction_of_fp32_peak"] > 0 and record["spread"]["batch"] >= 1.0
        if record["form"] == "torch fp32":
            assert FP32_KEYS <= set(record) and record["batch_speedup_over_fp32"] == 1.0
            assert set(record["peaks_gflops"]) == {"fp32", "bf16", "int8"} and record["memory_gbps"] > 0
    for record in result["training"]:
        assert record["train_step_samples_per_s"] > 0 and record["bound_train_samples_per_s"] > 0
        assert record["train_loop_samples_per_s"] > 0  # the shipped mocap is there (../shared)
    assert {r["model"] for r in result["streams"]} == {"videopose3d", "poselifter"}
    assert all(r["stream_ms_fp32"] > 0 and r["stream_ms_int8"] > 0 for r in result["streams"])
    assert result["video"] is None
    out_text = capsys.readouterr().out
    assert "GFLOP/s" in out_text and "interleaved rounds" in out_text


def test_interleaved_rounds_rotate_the_order_and_time_every_run_once_per_round():
    from ray3d.bench.speed import interleaved

    calls = []
    values = interleaved({name: (lambda n=name: calls.append(n) or len(calls)) for name in "abc"}, rounds=3, warmup=0)
    assert calls == list("abc" "bca" "cab")  # every run once per round, each round starting one further on
    assert {name: list(v) for name, v in values.items()} == {"a": [1, 6, 8], "b": [2, 4, 9], "c": [3, 5, 7]}


def test_layer_gemm_paths_name_the_kernels_each_layer_type_runs():
    from ray3d.bench.machine import layer_gemm_paths
    from ray3d.bench.speed import _batch
    from ray3d.models import PRESETS, LiftingNetwork

    model = LiftingNetwork(PRESETS["ray3d"]).eval()
    paths = layer_gemm_paths(model, _batch(model, 4))
    assert set(paths) == {"FrameGroupLinear", "Linear"}  # every matrix product of Ray3D is one of the two
    assert paths["FrameGroupLinear"] == ["aten::mm"]  # no bias: a plain product
    assert set(paths["Linear"]) <= {"aten::addmm", "aten::mm"}
    attention = LiftingNetwork(PRESETS["poseformer"]).eval()
    assert "MultiheadAttention" in layer_gemm_paths(attention, _batch(attention, 4))


def test_bounds_follow_from_the_peak_and_the_bandwidth():
    from ray3d.bench.speed import bounds, memory_run

    limits = bounds(params=1_000_000, flops=2e6, peak_gflops=100.0, bandwidth_gbps=10.0)
    assert limits["bound_batch_frames_per_s"] == pytest.approx(50_000)
    assert limits["bound_train_samples_per_s"] == pytest.approx(50_000 / 3)
    assert limits["bound_latency_ms"] == pytest.approx(0.4)  # 4 MB of fp32 weights at 10 GB/s
    run, read = memory_run(megabytes=64)
    assert run() == 0.0  # the first, untimed call sizes the rounds
    assert read == 64 * 2**20 and 0.1 < read / run() / 1e9 < 1000


def test_an_existing_json_is_refused_before_any_measuring(tmp_path, capsys, monkeypatch):
    import ray3d.bench.speed as speed

    def measured(*args, **kwargs):
        raise AssertionError("measured before refusing the output")

    monkeypatch.setattr(speed, "measure_all", measured)
    out = tmp_path / "speed.json"
    out.write_text("earlier results")
    assert main(["bench", "speed", "--models", "poselifter", "--json", str(out)]) == 2
    assert out.read_text() == "earlier results"
    assert "already exists" in capsys.readouterr().err
