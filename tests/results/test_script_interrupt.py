"""Ctrl-C during a benchmark script's grid ends it as it ends ``sb3-adc benchmark``: a message and exit status 130."""

from __future__ import annotations

from typing import Any

import pytest

from sb3_adc.experiment.benchmark import INTERRUPTED, run_script

# Each script that trains a grid, the engine entry it calls and arguments that reach it.
SCRIPTS = [
    ("critic_diagnostics", "run_benchmark", ["--quick"]),
]


def ctrl_c(*_: Any, **__: Any) -> None:
    # What the engine raises when Ctrl-C reaches a grid (each run in progress saved its checkpoint first).
    raise KeyboardInterrupt


@pytest.mark.parametrize(("script", "runner", "argv"), SCRIPTS, ids=[script for script, _, _ in SCRIPTS])
def test_ctrl_c_in_a_benchmark_script_exits_130_with_the_resume_message(script_main, capsys, script, runner, argv):
    module = script_main(script, runner, ctrl_c, argv)
    assert module.run_script is run_script  # its entry point is the one tested here
    with pytest.raises(SystemExit) as exit_info:
        run_script(module.main)
    assert exit_info.value.code == 130
    assert INTERRUPTED in capsys.readouterr().err


def test_run_script_exits_with_the_status_main_returns():
    with pytest.raises(SystemExit) as exit_info:
        run_script(lambda: 3)
    assert exit_info.value.code == 3
    with pytest.raises(SystemExit) as exit_info:
        run_script(lambda: None)
    assert exit_info.value.code == 0


def test_other_errors_keep_their_traceback():
    def broken() -> None:
        raise ValueError("a bug")

    with pytest.raises(ValueError, match="a bug"):
        run_script(broken)
