"""The record of the invocations that worked on a benchmark grid (``invocations.json``): written as runs finish and
on a heartbeat, so an invocation cut short keeps its time; merged over a grid's folders."""

from __future__ import annotations

import json
import textwrap
import time

import pytest

from sb3_adc.experiment.benchmark import BenchmarkSettings, run_benchmark
from sb3_adc.experiment.invocations import INVOCATIONS_JSON, InvocationJournal, read_invocations

TINY_TD3 = """\
Pendulum-v1:
  n_timesteps: 100
  policy: MlpPolicy
  learning_starts: 50
  batch_size: 16
  buffer_size: 1000
  policy_kwargs: "dict(net_arch=[8])"
"""


def grid(tmp_path, seeds=(1, 2)) -> BenchmarkSettings:
    conf = tmp_path / "conf"
    conf.mkdir(exist_ok=True)
    (conf / "td3.yml").write_text(textwrap.dedent(TINY_TD3))
    return BenchmarkSettings(
        algos=["td3"],
        env_ids=["Pendulum-v1"],
        seeds=list(seeds),
        log_folder=str(tmp_path / "grid"),
        conf_folder=str(conf),
        eval_freq=0,
        final_eval_episodes=1,
        device="cpu",
    )


def entries(folder) -> list[dict]:
    return json.loads((folder / INVOCATIONS_JSON).read_text())


def test_each_invocation_of_a_grid_is_recorded_with_what_it_ran(tmp_path):
    settings = grid(tmp_path)
    run_benchmark(settings, workers=1)
    run_benchmark(settings, workers=1)  # finds both runs finished
    first, second = entries(tmp_path / "grid")
    assert first["id"] != second["id"]
    assert first["runs"] == {"trained": 2, "resumed": 0, "skipped": 0, "failed": 0}
    assert second["runs"] == {"trained": 0, "resumed": 0, "skipped": 2, "failed": 0}
    for entry in (first, second):
        assert entry["finished"] is True
        assert entry["workers"] == 1
        assert entry["backend"] == "local"
        assert entry["algos"] == ["td3"]
        assert entry["runs_in_grid"] == 2
        assert entry["wall_time_s"] >= 0
    assert first["started"] <= second["started"]
    assert first["wall_time_s"] > second["wall_time_s"]


def test_an_invocation_stopped_by_ctrl_c_is_recorded_unfinished_with_the_runs_it_finished(tmp_path):
    def stop(outcome, done, total):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_benchmark(grid(tmp_path), workers=1, report=stop)
    (entry,) = entries(tmp_path / "grid")
    assert entry["finished"] is False
    assert entry["runs"]["trained"] == 1


def test_the_heartbeat_keeps_the_wall_time_of_an_invocation_that_is_killed(tmp_path):
    """A process killed without warning writes nothing more: what is on disk is the last heartbeat's."""
    now = [100.0]
    folder = str(tmp_path / "grid")
    journal = InvocationJournal([(folder, ["td3"], 3)], workers=2, backend="local", heartbeat_s=0.01, clock=lambda: now[0])
    with journal:
        assert entries(tmp_path / "grid")[0]["wall_time_s"] == 0.0
        now[0] = 160.5  # a minute of training, no run finished
        deadline = time.monotonic() + 10
        while entries(tmp_path / "grid")[0]["wall_time_s"] != 60.5:
            assert time.monotonic() < deadline, "no heartbeat"
            time.sleep(0.01)
        (entry,) = entries(tmp_path / "grid")
        assert entry["finished"] is False
        assert entry["runs"] == {"trained": 0, "resumed": 0, "skipped": 0, "failed": 0}
        now[0] = 170.0
        journal.record(folder, "resumed")
    (entry,) = entries(tmp_path / "grid")
    assert entry["finished"] is True
    assert entry["wall_time_s"] == 70.0
    assert entry["runs"]["resumed"] == 1


def test_an_invocation_over_several_grids_is_read_once(tmp_path):
    first, second = str(tmp_path / "a"), str(tmp_path / "b")
    with InvocationJournal([(first, ["adc"], 2), (second, ["adc"], 3)], workers=2, backend="local") as journal:
        journal.record(first, "trained")
        journal.record(second, "skipped")
        journal.record(second, "trained")
    with InvocationJournal([(second, ["td3"], 1)], workers=1, backend="local") as journal:
        journal.record(second, "failed")
    both, later = read_invocations([first, second, str(tmp_path / "none")])
    assert later["id"] == journal.id
    assert both["runs"] == {"trained": 2, "resumed": 0, "skipped": 1, "failed": 0}
    assert both["runs_in_grid"] == 5
    assert later["runs"]["failed"] == 1
    assert later["algos"] == ["td3"]


def test_an_unreadable_record_is_set_aside(tmp_path, capsys):
    folder = tmp_path / "grid"
    folder.mkdir()
    (folder / INVOCATIONS_JSON).write_text('[{"id": "a", "started": ')
    assert read_invocations([str(folder)]) == []
    assert "is unreadable" in capsys.readouterr().out
    assert (folder / (INVOCATIONS_JSON + ".damaged")).is_file()
    with InvocationJournal([(str(folder), ["td3"], 1)], workers=1, backend="local"):
        pass
    assert len(entries(folder)) == 1
