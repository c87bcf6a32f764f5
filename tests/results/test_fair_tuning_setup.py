"""The lidar study of ``benchmarks/fair_tuning.py`` starts every algorithm from its starting entry changed the same
way: each starting file differs from the ``-v1`` entry the studies began with (``benchmarks/configs/starting_entries/``)
only in the settings the budget sweeps found for every learner (and, for ADC, in the update settings they found for
it), so no baseline starts handicapped."""

from __future__ import annotations

import importlib
import json
import sys
from pathlib import Path

import pytest

from sb3_adc.config.loader import read_hyperparams_file, select_entry

ROOT = Path(__file__).resolve().parents[2]
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


@pytest.fixture(scope="module")
def fair_tuning():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    yield importlib.import_module("fair_tuning")
    sys.path.remove(str(ROOT / "benchmarks"))


@pytest.mark.parametrize("algo", ["adc", "ddpg", "td3", "sac"])
def test_starting_file_is_the_starting_entry_changed_alike(fair_tuning, algo):
    study = fair_tuning.STUDIES["lidar"]
    env_id = study.env_id
    path = study.starting_points[algo]
    start, _ = select_entry(read_hyperparams_file(path), env_id, path)
    entry_path = str(STARTING_ENTRIES / f"{algo}.yml")
    entry, _ = select_entry(read_hyperparams_file(entry_path), env_id, entry_path)
    for key, value in COMMON.items():
        assert start[key] == value, key
    # The fixed settings of the study agree with the starting entries.
    for key, value in study.fixed.items():
        assert start[key] == value, key
    allowed = set(COMMON) | (ADC_ONLY if algo == "adc" else set())
    changed = {key for key in set(start) | set(entry) if start.get(key) != entry.get(key)}
    assert changed <= allowed, changed - allowed
    if algo == "adc":
        assert start["policy_delay"] == 2
        assert start["target_policy_noise"] == 0.2
        assert "n_critics=2" in start["policy_kwargs"]


def test_report_only_invocation_keeps_the_training_invocations_metadata(fair_tuning, tmp_path, monkeypatch):
    """A second invocation of a finished study trains nothing: it must not add wall time, nor replace the workers
    (and machine) of the invocation that trained with its own."""
    monkeypatch.setattr(fair_tuning, "RUNS_DIR", tmp_path / "runs" / "fair_tuning")
    monkeypatch.setattr(fair_tuning, "RESULTS_DIR", tmp_path / "results" / "fair_tuning")
    metadata_path = tmp_path / "results" / "fair_tuning_quick" / "metadata.json"

    def invoke(workers: int) -> dict:
        monkeypatch.setattr(sys, "argv", ["fair_tuning.py", "--quick", "--algos", "ddpg", "--workers", str(workers)])
        fair_tuning.main()
        return json.loads(metadata_path.read_text())

    trained = invoke(1)
    assert trained["workers"] == 1
    assert trained["wall_time_s"]["ddpg"] > 0
    reported = invoke(2)
    assert reported["workers"] == 1
    assert reported["wall_time_s"] == trained["wall_time_s"]
    assert reported["trial_time_s"] == trained["trial_time_s"]
