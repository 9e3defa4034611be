"""``ray3d bench speed`` end to end on a tiny configuration: well-formed JSON with the documented keys."""

from __future__ import annotations

import json

import pytest

from ray3d.cli import main

KEYS = {"model", "preset", "backend", "params", "mflops_per_frame", "batch_frames_per_s", "sequence_frames_per_s",
        "latency_ms", "stream_ms_per_frame", "train_samples_per_s", "gemm_path"}
TORCH_KEYS = {"train_loop_samples_per_s", "layer_gemm_paths", "training_form", "bound_batch_frames_per_s",
              "bound_train_samples_per_s", "bound_latency_ms"}


def test_bench_speed_writes_the_documented_json(tmp_path, capsys):
    out = tmp_path / "speed.json"
    assert main(["bench", "speed", "--models", "videopose3d", "poselifter", "--repeats", "1", "--batch", "16",
                 "--sequence-frames", "64", "--train-batch", "16", "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["matmul_peak_gflops"] > 0
    assert [r["model"] for r in result["models"] if r["backend"] == "torch"] == ["videopose3d", "poselifter"]
    assert {"torch", "torchscript"} <= {r["backend"] for r in result["models"]} <= {"torch", "torchscript", "onnxruntime"}
    for record in result["models"]:
        assert KEYS <= set(record)
        assert record["params"] > 0 and record["batch_frames_per_s"] > 0 and record["latency_ms"] > 0
        assert (record["train_samples_per_s"] is None) == (record["backend"] != "torch")
        assert f"{record['gemm_path']}_gflops" in result["matmul_paths_gflops"]
        if record["backend"] == "torch":
            assert TORCH_KEYS <= set(record)
            assert record["train_loop_samples_per_s"] > 0  # the shipped mocap is there (../shared)
            assert record["bound_batch_frames_per_s"] > 0 and record["layer_gemm_paths"]
            assert record["training_form"]["latency_ms"] > 0 and record["training_form"]["batch_frames_per_s"] > 0
    assert result["memory_gbps"] > 0 and result["blas"] and result["video"] is None
    out_text = capsys.readouterr().out
    assert "GFLOP/s" in out_text and "bounds" in out_text


def test_layer_gemm_paths_name_the_kernels_each_layer_type_runs():
    from ray3d.bench.speed import _batch, layer_gemm_paths
    from ray3d.models import PRESETS, LiftingNetwork

    model = LiftingNetwork(PRESETS["ray3d"]).eval()
    paths = layer_gemm_paths(model, _batch(model, 4))
    assert set(paths) == {"FrameGroupLinear", "Linear"}  # every matrix product of Ray3D is one of the two
    assert paths["FrameGroupLinear"] == ["aten::mm"]  # no bias: a plain product
    assert set(paths["Linear"]) <= {"aten::addmm", "aten::mm"}
    attention = LiftingNetwork(PRESETS["poseformer"]).eval()
    assert "MultiheadAttention" in layer_gemm_paths(attention, _batch(attention, 4))


def test_bounds_follow_from_the_peak_and_the_bandwidth():
    from ray3d.bench.speed import bounds, memory_gbps

    limits = bounds(params=1_000_000, flops=2e6, peak_gflops=100.0, bandwidth_gbps=10.0)
    assert limits["bound_batch_frames_per_s"] == pytest.approx(50_000)
    assert limits["bound_train_samples_per_s"] == pytest.approx(50_000 / 3)
    assert limits["bound_latency_ms"] == pytest.approx(0.4)  # 4 MB of fp32 weights at 10 GB/s
    assert 0.1 < memory_gbps(megabytes=64, repeats=3) < 1000


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
