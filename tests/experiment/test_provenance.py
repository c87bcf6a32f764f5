"""The versions and machine that close every benchmark's metadata.json."""

from __future__ import annotations

import json
import platform
from pathlib import Path

import pytest

import sb3_adc
from sb3_adc.experiment import provenance


def test_machine_metadata_names_versions_and_machine():
    metadata = provenance.machine_metadata()
    assert list(metadata) == ["sb3_adc", "stable_baselines3", "torch", "python", "machine", "cpu_count", "cpu"]
    assert metadata["sb3_adc"] == sb3_adc.__version__
    assert metadata["python"] == platform.python_version()
    assert json.loads(json.dumps(metadata)) == metadata  # written as JSON as it is


@pytest.mark.parametrize(
    ("cpuinfo", "processor", "expected"),
    [
        ("processor\t: 0\nmodel name\t: Test CPU 9000 @ 3.00GHz\nflags\t: fpu\n", "x86_64", "Test CPU 9000 @ 3.00GHz"),
        ("processor\t: 0\nflags\t: fpu\n", "arm", "arm"),  # no model name line (some ARM kernels)
        (None, "", "unknown"),  # no /proc/cpuinfo, nothing from platform
    ],
)
def test_cpu_model_reads_cpuinfo_then_falls_back(monkeypatch, cpuinfo, processor, expected):
    def read_text(self, *args, **kwargs):
        if cpuinfo is None:
            raise OSError("no /proc")
        return cpuinfo

    monkeypatch.setattr(Path, "read_text", read_text)
    monkeypatch.setattr(platform, "processor", lambda: processor)
    assert provenance.cpu_model() == expected
