"""The lidar study of ``benchmarks/experiments/fair_tuning_lidar.yml`` starts every algorithm from its starting entry
changed the same way: each starting file differs from the ``-v1`` entry the studies began with
(``benchmarks/configs/starting_entries/``) only in the settings the budget sweeps found for every learner (and, for
ADC, in the update settings they found for it), so no baseline starts handicapped."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from sb3_adc.cli import main
from sb3_adc.config.loader import read_hyperparams_file, select_entry
from sb3_adc.experiment.experiments import read_experiment
from sb3_adc.experiment.tuning_grid import study_settings

ROOT = Path(__file__).resolve().parents[2]
LIDAR_STUDY = ROOT / "benchmarks" / "experiments" / "fair_tuning_lidar.yml"
STARTING_ENTRIES = ROOT / "benchmarks" / "configs" / "starting_entries"
#: What every starting entry changes, with the values the budget sweeps found.
COMMON = {
    "n_timesteps": 150_000,
    "gamma": 0.98,
    "buffer_size": 200_000,
    "env_wrapper": [{"sb3_adc_envs.wrappers.ClearanceShaping": {"gamma": 0.98}}],
}
#: ADC's own changes: TD3's additions and the lower actor rate.
ADC_ONLY = {"learning_rate", "policy_delay", "target_policy_noise", "target_noise_clip", "policy_kwargs"}


@pytest.mark.parametrize("algo", ["adc", "ddpg", "td3", "sac"])
def test_starting_file_is_the_starting_entry_changed_alike(algo):
    study = study_settings(read_experiment(str(LIDAR_STUDY)), algo)
    env_id, path = study.env_id, str(study.conf_file)
    start, _ = select_entry(read_hyperparams_file(path), env_id, path)
    entry_path = str(STARTING_ENTRIES / f"{algo}.yml")
    entry, _ = select_entry(read_hyperparams_file(entry_path), env_id, entry_path)
    for key, value in COMMON.items():
        assert start[key] == value, key
    # The fixed settings of the study agree with the starting entries.
    assert study.overrides
    for key, value in study.overrides.items():
        assert start[key] == value, key
    allowed = set(COMMON) | (ADC_ONLY if algo == "adc" else set())
    changed = {key for key in set(start) | set(entry) if start.get(key) != entry.get(key)}
    assert changed <= allowed, changed - allowed
    if algo == "adc":
        assert start["policy_delay"] == 2
        assert start["target_policy_noise"] == 0.2
        assert "n_critics=2" in start["policy_kwargs"]


#: A tuning file of two tiny studies.
TINY_TUNING = """
envs: [Pendulum-v1]
seeds: [0]
n_timesteps: 200
evaluation: {episodes: 1, final_episodes: 1}
configs:
  ddpg: {algo: ddpg, overrides: {learning_starts: 50, batch_size: 16, policy_kwargs: "dict(net_arch=[8])"}}
tuning: {trials: 2, n_startup_trials: 1}
"""


def test_report_only_invocation_keeps_the_training_invocations_metadata(tmp_path, capsys):
    """A second invocation of a finished study trains nothing: it must not add wall time, nor replace the workers
    (and machine) of the invocation that trained with its own; ``--report`` rewrites the summary alone."""
    path = tmp_path / "experiments" / "probe.yml"
    path.parent.mkdir()
    path.write_text(TINY_TUNING)
    results = tmp_path / "results" / "probe"
    metadata_path = results / "metadata.json"

    def invoke(workers: int) -> dict:
        assert main(["experiment", str(path), "--workers", str(workers)]) == 0
        return json.loads(metadata_path.read_text())

    trained = invoke(1)
    assert trained["workers"] == 1
    assert trained["wall_time_s"]["ddpg"] > 0
    assert trained["n_trials"] == 2
    assert (tmp_path / "runs" / "probe" / "tuning" / "ddpg-Pendulum-v1" / "study.log").is_file()
    assert (results / "ddpg" / "trials.csv").is_file()
    assert (results / "hyperparams" / "ddpg.yml").is_file()
    reported = invoke(2)
    assert reported["workers"] == 1
    assert reported["wall_time_s"] == trained["wall_time_s"]
    assert reported["trial_time_s"] == trained["trial_time_s"]
    summary = (results / "summary.md").read_text()
    (results / "summary.md").unlink()
    capsys.readouterr()
    assert main(["experiment", str(path), "--report"]) == 0
    assert (results / "summary.md").read_text() == summary
    assert "| ddpg | 2 |" in capsys.readouterr().out
    assert json.loads(metadata_path.read_text()) == reported


def test_a_killed_invocation_keeps_its_time_in_the_studys_wall_time(tmp_path):
    """An invocation stopped by a kill writes no metadata, but its journal entry in the study's folder stays: the
    invocation that finishes the study reports the time of both."""
    path = tmp_path / "experiments" / "probe.yml"
    path.parent.mkdir()
    path.write_text(TINY_TUNING)
    study = tmp_path / "runs" / "probe" / "tuning" / "ddpg-Pendulum-v1"
    study.mkdir(parents=True)
    killed = {"id": "killed", "started": "2026-01-01T00:00:00+00:00", "wall_time_s": 1234.5, "workers": 1}
    killed |= {"backend": "local", "algos": ["ddpg"], "runs_in_grid": 2, "runs": {"trained": 1}, "finished": False}
    (study / "invocations.json").write_text(json.dumps([killed]))
    assert main(["experiment", str(path), "--workers", "1"]) == 0
    entries = json.loads((study / "invocations.json").read_text())
    assert entries[0]["id"] == "killed"
    assert len(entries) == 2
    finishing = entries[1]
    assert finishing["finished"]
    assert finishing["runs"]["trained"] == 2
    metadata = json.loads((tmp_path / "results" / "probe" / "metadata.json").read_text())
    assert metadata["wall_time_s"]["ddpg"] == round(1234.5 + finishing["wall_time_s"], 1)
