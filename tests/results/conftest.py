"""Shared helpers of the tests of the benchmark scripts."""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def grid_settings(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Callable[[str, str, list[str]], list[Any]]:
    """
    ``grid_settings(script, runner, argv)``: the grid settings a benchmark script (``benchmarks/{script}.py``)
    hands its training engine for ``argv``, stopped before any training: the script's ``runner``
    (``run_benchmark`` or ``run_benchmarks``) is replaced by one that records its settings and stops, and its run
    and result folders point into ``tmp_path``.
    """
    return lambda script, runner, argv: _grid_settings(tmp_path, monkeypatch, script, runner, argv)


def _grid_settings(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, script: str, runner: str, argv: list[str]) -> list[Any]:
    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    module = importlib.import_module(script)
    monkeypatch.setattr(module, "RUNS_DIR", tmp_path / "runs")
    monkeypatch.setattr(module, "RESULTS_DIR", tmp_path / "results")
    recorded: list[Any] = []

    class Stop(Exception):
        pass

    def stop(settings: Any, **_: Any) -> None:
        recorded.extend(settings if isinstance(settings, list) else [settings])
        raise Stop

    monkeypatch.setattr(module, runner, stop)
    monkeypatch.setattr(sys, "argv", [f"{script}.py", *argv])
    try:
        with pytest.raises(Stop):
            module.main()
    finally:
        # The scripts import each other (budget_sweep uses procedural_generalisation): forget both.
        for name in (script, "budget_sweep", "procedural_generalisation"):
            sys.modules.pop(name, None)
    return recorded
