"""
What a results folder was made with: the versions and the machine, the closing keys of every benchmark's
``metadata.json``. A run's exact digits depend on them (float rounding differs across processors and library
versions), so a number that does not repeat elsewhere can be traced to a difference here.
"""

from __future__ import annotations

import os
import platform
from pathlib import Path
from typing import Any

import stable_baselines3
import torch as th

import sb3_adc


def cpu_model() -> str:
    """The processor's model name from ``/proc/cpuinfo``, else what :func:`platform.processor` says, else ``"unknown"``."""
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        lines = []
    name = next((line.split(":", 1)[1].strip() for line in lines if line.startswith("model name")), "")
    return name or platform.processor() or "unknown"


def machine_metadata() -> dict[str, Any]:
    """The versions (sb3-adc, Stable-Baselines3, PyTorch, Python) and the machine (architecture, cores, processor)."""
    return {
        "sb3_adc": sb3_adc.__version__,
        "stable_baselines3": stable_baselines3.__version__,
        "torch": th.__version__,
        "python": platform.python_version(),
        "machine": platform.machine(),
        "cpu_count": os.cpu_count(),
        "cpu": cpu_model(),
    }
