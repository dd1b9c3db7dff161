"""The machine a job ran on, as MLflow tags: CPU model and SIMD flags, GPU, library versions.

Timings and (for the CNN-GRU, whose ``device`` and ``precision`` default to
``auto``) results depend on the hardware, so every job records it
(:meth:`sphri.tracking.mlflow_tracker.MlflowTracker.log_job`), and the
benchmarks' rows use the same description (``bench/_common.machine``).
Reading it imports no compute library: versions come from the installed
packages' metadata, the GPU from torch only when the job already imported it.
"""

from __future__ import annotations

import os
import platform
import sys
from importlib import metadata
from pathlib import Path

#: The CPU flags that change which kernels numpy, MKL/oneDNN and torch run (AVX2 vs AVX-512, native bf16).
SIMD_FLAGS = tuple("avx avx2 fma avx512f avx512bw avx512_vnni avx512_bf16 amx_bf16 amx_tile asimd sve".split())

#: Libraries whose version can change a job's numbers or its speed.
LIBRARIES = ("numpy", "scipy", "scikit-learn", "torch", "numba")


def cpu() -> dict[str, str | int]:
    """``cpu_model`` (``/proc/cpuinfo``'s model name, else the platform's), ``cpu_flags`` (the
    :data:`SIMD_FLAGS` it has, space-separated) and ``cpu_count`` (logical CPUs of the machine)."""
    model = platform.processor() or platform.machine()
    flags: list[str] = []
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = line.partition(":")
            key = key.strip()
            if key in ("model name", "Model") and model in ("", platform.machine(), platform.processor()):
                model = value.strip()
            elif key in ("flags", "Features") and not flags:
                flags = [f for f in value.split() if f in SIMD_FLAGS]
    except OSError:
        pass
    return {"cpu_model": model, "cpu_flags": " ".join(flags), "cpu_count": os.cpu_count() or 0}


def libraries() -> dict[str, str]:
    """Installed version of each of :data:`LIBRARIES` (``"absent"`` when not installed) and Python's."""

    def version(name: str) -> str:
        try:
            return metadata.version(name)
        except metadata.PackageNotFoundError:
            return "absent"

    return {"python": platform.python_version(), **{name: version(name) for name in LIBRARIES}}


def gpu() -> str:
    """The first CUDA device's name when this process imported torch and torch sees one; ``"none"``."""
    torch = sys.modules.get("torch")
    if torch is None:
        return "none (torch not used)"
    try:
        return torch.cuda.get_device_name(0) if torch.cuda.is_available() else "none"
    except Exception as exc:  # noqa: BLE001 - a broken driver must not fail the job's record
        return f"unknown ({type(exc).__name__})"


def tags() -> dict[str, str]:
    """MLflow tags ``sphri.machine.*`` (CPU, GPU) and ``sphri.lib.*`` (versions) of this process."""
    out = {f"sphri.machine.{k}": str(v) for k, v in cpu().items()}
    out["sphri.machine.gpu"] = gpu()
    out.update({f"sphri.lib.{k}": v for k, v in libraries().items()})
    return out
