"""A one-line description of the machine a benchmark ran on, for honest reports."""

from __future__ import annotations

import os
import platform

import numpy as np


def describe_machine() -> dict:
    cpu = platform.processor() or platform.machine()
    fields: dict[str, str] = {}
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                name, _, value = line.partition(":")
                fields.setdefault(name.strip(), value.strip())
    except OSError:
        pass
    cpu = fields.get("model name", cpu)
    # Machines sold under one name differ in generation: the family, model and vector units tell them apart.
    if "cpu family" in fields:
        units = [unit for unit in ("avx2", "avx512f", "avx512_bf16", "amx_bf16") if unit in fields.get("flags", "").split()]
        cpu += f" (family {fields['cpu family']} model {fields.get('model', '?')}; {', '.join(units) or 'no AVX2'})"
    try:
        import torch

        torch_version = torch.__version__
    except ImportError:
        torch_version = None
    return {
        "cpu": cpu,
        "cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "torch": torch_version,
        "system": f"{platform.system()} {platform.release()}",
    }
