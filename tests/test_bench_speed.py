"""``ray3d bench speed`` end to end on a tiny configuration: well-formed JSON with the documented keys."""

from __future__ import annotations

import json

from ray3d.cli import main

KEYS = {"model", "preset", "backend", "params", "mflops_per_frame", "batch_frames_per_s", "sequence_frames_per_s",
        "latency_ms", "stream_ms_per_frame", "train_samples_per_s", "gemm_path"}


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
    assert "GFLOP/s" in capsys.readouterr().out
