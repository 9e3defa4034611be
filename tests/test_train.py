"""Training: the loss falls, checkpoints round-trip exactly, resuming continues, two gloo processes train as one."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys

import pytest
import torch

from ray3d.checkpoints import load_model, read_checkpoint
from ray3d.errors import InputError
from ray3d.models import LiftingNetwork, preset
from ray3d.train import TrainConfig, batch_tensors, train, validation_batch


def _config(data_dir, **overrides) -> TrainConfig:
    base = dict(model=preset("ray3d", channels=32, hidden=64), epochs=2, batches_per_epoch=8, batch_size=128,
                validation_samples=256, data_dir=str(data_dir), threads=1)
    return TrainConfig(**{**base, **overrides})


def test_a_few_steps_reduce_the_loss(tiny_data_dir, tmp_path):
    state = train(_config(tiny_data_dir, epochs=3, batches_per_epoch=15), tmp_path / "run", progress=False)
    losses = [h["loss"] for h in state["history"]]
    assert losses[-1] < 0.7 * losses[0]
    assert state["best"]["abs_mpjpe_mm"] == min(h["abs_mpjpe_mm"] for h in state["history"])


def test_save_load_gives_identical_outputs_and_resume_continues(tiny_data_dir, tmp_path):
    config = _config(tiny_data_dir)
    run = tmp_path / "run"
    first = train(config, run, progress=False)
    assert [h["epoch"] for h in first["history"]] == [1, 2]
    model, document = load_model(run / "best.safetensors")
    assert "CMU" in document["trained_on"] and "CC BY-SA 3.0" in document["trained_on"]
    batch = batch_tensors(validation_batch(config))
    tensors, _ = read_checkpoint(run / "best.safetensors")
    again, _ = load_model(run / "best.safetensors")
    with torch.no_grad():
        torch.testing.assert_close(model(batch), again(batch), rtol=0, atol=0)
    with pytest.raises(Exception, match="resume it or choose another output folder"):
        train(config, run, progress=False)
    resumed = train(TrainConfig(**{**config.to_dict(), "epochs": 3}), run, resume=True, progress=False)
    assert [h["epoch"] for h in resumed["history"]] == [1, 2, 3]
    assert resumed["history"][:2] == first["history"]
    assert json.loads((run / "last.json").read_text())["epoch"] == 3
    assert not any(k.startswith("optimizer.") for k in tensors)  # best holds weights only


def test_training_is_deterministic_with_a_seed(tiny_data_dir, tmp_path):
    config = _config(tiny_data_dir, epochs=1, batches_per_epoch=3)
    a = train(config, tmp_path / "a", progress=False)["history"][0]
    b = train(config, tmp_path / "b", progress=False)["history"][0]
    assert a["loss"] == b["loss"] and a["abs_mpjpe_mm"] == b["abs_mpjpe_mm"]


def test_two_gloo_processes_with_batch_b_train_as_one_with_batch_2b(tiny_data_dir, tmp_path):
    """torchrun, 2 CPU processes, one step: the same weights and batch-norm statistics as one process."""
    config = _config(tiny_data_dir, model=preset("ray3d", channels=32, hidden=64, dropout=0.0), epochs=1,
                     batches_per_epoch=1, batch_size=128)
    config_path = tmp_path / "config.json"
    config_path.write_text(json.dumps(config.to_dict()))
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    result = subprocess.run(
        [sys.executable, "-m", "torch.distributed.run", "--nproc_per_node=2", "--master_port=29533", "-m",
         "ray3d.cli", "train", "--config", str(config_path), "--out", str(tmp_path / "ddp"), "--quiet"],
        capture_output=True, text=True, timeout=300, env=env)
    assert result.returncode == 0, result.stderr[-2000:]
    assert "best epoch 1" in result.stdout
    train(config, tmp_path / "one", progress=False)
    two, _ = read_checkpoint(tmp_path / "ddp" / "last.safetensors")
    one, _ = read_checkpoint(tmp_path / "one" / "last.safetensors")
    torch.manual_seed(config.seed)
    initial = LiftingNetwork(config.model)
    beta1 = 0.9  # Adam's first moment after one step is (1 - beta1) x the gradient
    for index, (name, start) in enumerate(initial.named_parameters()):
        gradient = one[f"optimizer.{index}.exp_avg"] / (1 - beta1)
        other = two[f"optimizer.{index}.exp_avg"] / (1 - beta1)
        assert (other - gradient).abs().max() <= 5e-3 * gradient.abs().max() + 1e-5, name  # summed in another order
        # Adam's first step moves each weight by the learning rate times the sign of its gradient, so where the
        # gradient is rounding noise (e.g. biases before a batch norm) the sign, and the step, is noise too.
        clear = gradient.abs() > 1e-5
        torch.testing.assert_close(two[f"model.{name}"][clear], one[f"model.{name}"][clear], rtol=0, atol=1e-5,
                                   msg=name)
        if clear.any():
            assert not torch.equal(one[f"model.{name}"][clear], start.detach()[clear])  # the step moved them
    statistics = [k for k in one if k.startswith("model.") and "running_" in k]
    assert statistics
    for key in statistics:
        torch.testing.assert_close(two[key], one[key], rtol=0, atol=1e-5, msg=key)


def test_export_keeps_weights_and_provenance_only(tiny_data_dir, tmp_path):
    from ray3d import InputError
    from ray3d.checkpoints import export

    run = tmp_path / "run"
    train(_config(tiny_data_dir, epochs=1, batches_per_epoch=2), run, progress=False)
    target = export(run / "last.safetensors", tmp_path / "shipped" / "mine", training={"command": "ray3d train"})
    tensors, document = read_checkpoint(target)
    assert all(k.startswith("model.") for k in tensors)
    assert document["training"]["command"] == "ray3d train" and "trained_on" in document
    model, _ = load_model(target)
    reference, _ = load_model(run / "last.safetensors")
    batch = batch_tensors(validation_batch(_config(tiny_data_dir)))
    with torch.no_grad():
        torch.testing.assert_close(model(batch), reference(batch), rtol=0, atol=0)
    with pytest.raises(InputError, match="already exists"):
        export(run / "last.safetensors", target)


def test_training_on_one_dataset_only(tiny_data_dir, tmp_path):
    config = TrainConfig.from_json(_write(tmp_path / "c.json", {"datasets": ["cmu"], "epochs": 1}))
    assert config.datasets == ("cmu",)
    train(_config(tiny_data_dir, datasets=("cmu",), epochs=1, batches_per_epoch=2), tmp_path / "cmu", progress=False)
    with pytest.raises(InputError, match="holds none of hdm05_h36m17.npz"):
        train(_config(tiny_data_dir, datasets=("hdm05",), epochs=1), tmp_path / "hdm05", progress=False)
    with pytest.raises(InputError, match="datasets"):
        train(_config(tiny_data_dir, datasets=("h36m",), epochs=1), tmp_path / "h36m", progress=False)


def _write(path, document):
    path.write_text(json.dumps(document))
    return path


def test_a_config_names_a_preset_and_its_overrides(tmp_path):
    from ray3d.train import training_config

    path = _write(tmp_path / "c.json", {"preset": "rie", "model": {"name": "rie-small", "channels": 64},
                                        "epochs": 3, "samples": {"noise_px": 2.0}})
    config = training_config(path)
    assert config.model == preset("rie", name="rie-small", channels=64)
    assert config.epochs == 3 and config.samples.noise_px == 2.0 and config.batch_size == TrainConfig().batch_size
    swapped = training_config(path, "videopose3d", epochs=5, seed=None)
    assert swapped.model == preset("videopose3d") and swapped.epochs == 5 and swapped.samples.noise_px == 2.0
    # A saved config.json (the whole configuration, no preset) loads as it was.
    saved = _write(tmp_path / "saved.json", config.to_dict())
    assert TrainConfig.from_json(saved) == config
    with pytest.raises(InputError, match="unknown model preset 'nope'"):
        training_config(_write(tmp_path / "bad.json", {"preset": "nope"}))
    with pytest.raises(InputError, match="not a training config"):
        training_config(_write(tmp_path / "typo.json", {"preset": "ray3d", "epoch": 3}))


def test_averaged_weights_are_validated_shipped_and_resumed(tiny_data_dir, tmp_path):
    config = _config(tiny_data_dir, epochs=2, batches_per_epoch=6, ema_decay=0.99)
    run = tmp_path / "ema"
    first = train(config, run, progress=False)
    tensors, _ = read_checkpoint(run / "last.safetensors")
    assert int(tensors["ema_steps"]) == 12 and any(k.startswith("raw.") for k in tensors)
    shipped, _ = load_model(run / "last.safetensors")  # the averaged weights, as "model."
    differs = any(not torch.equal(tensors[f"raw.{k}"], v) for k, v in shipped.state_dict().items())
    assert differs
    from ray3d.checkpoints import export

    raw = load_model(export(run / "last.safetensors", tmp_path / "raw", averaged=False))[0]
    assert all(torch.equal(tensors[f"raw.{k}"], v) for k, v in raw.state_dict().items())
    resumed = train(TrainConfig(**{**config.to_dict(), "epochs": 3}), run, resume=True, progress=False)
    assert resumed["history"][:2] == first["history"] and int(read_checkpoint(run / "last.safetensors")[0]
                                                              ["ema_steps"]) == 18


def test_the_weight_average_copies_integer_buffers_and_averages_the_rest():
    from torch.optim.swa_utils import AveragedModel

    from ray3d.models import PRESETS, LiftingNetwork
    from ray3d.train import _warming_ema

    model = LiftingNetwork(PRESETS["ray3d"])
    ema = AveragedModel(model, avg_fn=_warming_ema(0.999), use_buffers=True)
    start = {k: v.clone() for k, v in model.state_dict().items()}
    for _ in range(30):  # float(15) * 0.9x + 15 * 0.0x rounds below 15: truncated before the fix
        ema.update_parameters(model)
    with torch.no_grad():
        for parameter in model.parameters():
            parameter.add_(1.0)
    ema.update_parameters(model)
    averaged = dict(ema.module.named_buffers())
    for name, buffer in model.named_buffers():
        if not buffer.is_floating_point():
            assert torch.equal(averaged[name], buffer), name
    weight = "pose_net.backbone.global_branch.0.weight"
    moved = ema.module.state_dict()[weight] - start[weight]
    assert 0 < float(moved.mean()) < 1  # between the old and the new weights


def test_a_config_on_a_base_lists_only_its_changes_and_a_loop_of_bases_is_refused(tmp_path):
    from ray3d.train import config_document

    _write(tmp_path / "base.json", {"preset": "ray3d", "epochs": 7, "samples": {"noise_px": 2.0, "cameras": {
        "roll_deg": 4.0, "pitch_deg": [0.0, 30.0]}}})
    _write(tmp_path / "child.json", {"base": "base.json", "model": {"name": "child"},
                                    "samples": {"cameras": {"roll_deg": 6.0}}})
    config = TrainConfig.from_json(tmp_path / "child.json")
    assert config.model.name == "child" and config.epochs == 7 and config.samples.noise_px == 2.0
    assert config.samples.cameras.roll_deg == 6.0 and config.samples.cameras.pitch_deg == (0.0, 30.0)
    _write(tmp_path / "a.json", {"base": "b.json"})
    _write(tmp_path / "b.json", {"base": "a.json", "preset": "ray3d"})
    with pytest.raises(InputError, match="its bases name it again"):
        config_document(tmp_path / "a.json")


def test_fine_tuning_starts_from_the_given_weights(tiny_data_dir, tmp_path):
    """``init_from`` starts a run from a checkpoint's weights: with a learning rate of zero the run validates
    exactly as the checkpoint does; from fresh weights it does not."""
    first = train(_config(tiny_data_dir, epochs=1, batches_per_epoch=4), tmp_path / "first", progress=False)
    frozen = _config(tiny_data_dir, epochs=1, batches_per_epoch=2, learning_rate=0.0, seed=5,
                     init_from=str(tmp_path / "first" / "best.safetensors"))
    tuned = train(frozen, tmp_path / "tuned", progress=False)
    fresh = train(dataclasses.replace(frozen, init_from=None), tmp_path / "fresh", progress=False)
    assert tuned["best"]["mpjpe_mm"] == pytest.approx(first["best"]["mpjpe_mm"], rel=0.05)
    assert abs(fresh["best"]["mpjpe_mm"] - first["best"]["mpjpe_mm"]) > 1.0
    assert json.loads((tmp_path / "tuned" / "config.json").read_text())["init_from"].endswith("best.safetensors")
