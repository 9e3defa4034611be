"""What a speed figure was measured on: the CPU, its vector extensions, torch's CPU capability, the BLAS and
oneDNN kernels it runs (``machine``), and which matrix-product kernel each layer type of a model reaches
(``layer_gemm_paths``). ``ray3d bench speed`` records them beside every figure."""

from __future__ import annotations

import os
import platform
import sys
import tempfile
from pathlib import Path

import torch

from ray3d.models.precision import bf16_native

_MATMUL_OPS = frozenset({"mm", "addmm", "bmm", "baddbmm", "addmv", "mv", "mkldnn_linear", "convolution",
                         "_mkldnn_convolution", "_native_multi_head_attention",
                         "_scaled_dot_product_flash_attention_for_cpu"})


def machine() -> dict:
    """What ran the figures: the CPU, its cores and vector extensions, torch's kernel choices."""
    flags: set[str] = set()
    model = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("flags"):
                flags = set(line.split(":", 1)[1].split())
            elif line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
    except OSError:
        pass
    return {"cpu": model, "cores": os.cpu_count(), "torch": torch.__version__, "torch_threads": torch.get_num_threads(),
            "vector_extensions": sorted(f for f in flags if f.startswith(("avx512", "amx")) or f in ("avx2", "fma")),
            "cpu_capability": torch.backends.cpu.get_cpu_capability(), "blas": blas_library(),
            "bf16_native": bf16_native(), "quantized_engine": torch.backends.quantized.engine,
            "onednn_kernels": onednn_kernels()}


def onednn_kernels() -> list[str]:
    """The oneDNN implementations (with their instruction set) a bf16 linear layer runs, from oneDNN's verbose
    log of one call; fp32 linear layers run the BLAS above, int8 ones the quantized engine."""
    layer, x = torch.nn.Linear(256, 256).to(torch.bfloat16), torch.randn(64, 256).to(torch.bfloat16)
    with tempfile.TemporaryFile() as log:
        sys.stdout.flush()
        saved = os.dup(1)
        os.dup2(log.fileno(), 1)  # oneDNN writes to the process's stdout
        try:
            with torch.no_grad(), torch.backends.mkldnn.verbose(torch.backends.mkldnn.VERBOSE_ON):
                layer(x)
        finally:
            os.dup2(saved, 1)
            os.close(saved)
        log.seek(0)
        lines = log.read().decode(errors="replace").splitlines()
    return sorted({line.split(",")[5] + " " + line.split(",")[6] for line in lines if ",exec,cpu," in line})


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
