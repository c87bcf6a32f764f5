"""Shared helpers of the tests of the benchmark scripts."""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def script_main(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> Iterator[Callable[[str, str, Callable[..., Any], list[str]], Any]]:
    """
    ``script_main(script, runner, replacement, argv)``: a benchmark script (``benchmarks/{script}.py``) imported
    with its run and result folders in ``tmp_path``, its ``runner`` (``run_benchmark`` or ``run_benchmarks``)
    replaced and ``sys.argv`` set to ``argv``; returns the module, whose ``main`` the test calls.
    """
    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    imported: list[str] = []

    def load(script: str, runner: str, replacement: Callable[..., Any], argv: list[str]) -> Any:
        module = importlib.import_module(script)
        imported.append(script)
        monkeypatch.setattr(module, "RUNS_DIR", tmp_path / "runs")
        monkeypatch.setattr(module, "RESULTS_DIR", tmp_path / "results")
        monkeypatch.setattr(module, runner, replacement)
        monkeypatch.setattr(sys, "argv", [f"{script}.py", *argv])
        return module

    yield load
    for name in imported:
        sys.modules.pop(name, None)


@pytest.fixture
def grid_settings(script_main: Callable[..., Any]) -> Callable[[str, str, list[str]], list[Any]]:
    """
    ``grid_settings(script, runner, argv)``: the grid settings a benchmark script (``benchmarks/{script}.py``)
    hands its training engine for ``argv``, stopped before any training: the script's ``runner``
    (``run_benchmark`` or ``run_benchmarks``) is replaced by one that records its settings and stops, and its run
    and result folders point into ``tmp_path``.
    """

    class Stop(Exception):
        pass

    def settings(script: str, runner: str, argv: list[str]) -> list[Any]:
        recorded: list[Any] = []

        def stop(settings: Any, **_: Any) -> None:
            recorded.extend(settings if isinstance(settings, list) else [settings])
            raise Stop

        module = script_main(script, runner, stop, argv)
        with pytest.raises(Stop):
            module.main()
        return recorded

    return settings
