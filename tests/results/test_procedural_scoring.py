"""The scoring of ``benchmarks/procedural_generalisation.py`` and ``benchmarks/budget_sweep.py`` on a real run: it
loads the model it is asked for (final, best or a checkpoint file), evaluates without the training-only start
jitter and reports one row per test set."""

from __future__ import annotations

import importlib
import sys
import textwrap
from pathlib import Path

import pytest
import torch as th
from stable_baselines3 import TD3

from sb3_adc.cli import main
from sb3_adc.experiment.layout import RunLayout

ROOT = Path(__file__).resolve().parents[2]
ENV_ID = "sb3_adc/LidarObstacleCourse-v1"
TINY_TD3 = """
    sb3_adc/LidarObstacleCourse-v1:
      n_timesteps: 300
      policy: MlpPolicy
      learning_starts: 100
      batch_size: 16
      buffer_size: 1000
      policy_kwargs: "dict(net_arch=[8])"
      env_kwargs: {max_episode_steps: 40, start_position_jitter: 0.2, start_heading_jitter_deg: 15.0}
    """


@pytest.fixture(scope="module")
def scripts():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        yield importlib.import_module("procedural_generalisation"), importlib.import_module("budget_sweep")
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
        sys.modules.pop("budget_sweep", None)
        sys.modules.pop("procedural_generalisation", None)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> str:
    folder = tmp_path_factory.mktemp("scoring")
    conf = folder / "td3.yml"
    conf.write_text(textwrap.dedent(TINY_TD3))
    args = ["train", "--algo", "td3", "--env", ENV_ID, "-conf", str(conf), "-f", str(folder / "logs"), "--seed", "3"]
    extra = ["--eval-freq", "100", "--eval-episodes", "1", "--final-eval-episodes", "1", "--save-freq", "100"]
    assert main([*args, *extra, "--no-progress-bar"]) == 0
    (run,) = (folder / "logs" / "td3").iterdir()
    return str(run)


def same_parameters(model, path: str) -> bool:
    saved = TD3.load(path, device="cpu").policy.state_dict()
    return all(th.equal(value, saved[key]) for key, value in model.policy.state_dict().items())


def test_scoring_loads_the_model_asked_for_without_training_jitter(scripts, run_dir):
    procedural, _ = scripts
    layout = RunLayout(run_dir, ENV_ID)
    checkpoint = layout.checkpoints()[0].model
    for which, path in [("final", layout.final_model), ("best", layout.best_model)]:
        settings, _, model, kwargs = procedural.load_for_scoring(run_dir, which)
        assert same_parameters(model, path)
        assert (settings.algo, settings.env_id) == ("td3", ENV_ID)
        assert kwargs == {"max_episode_steps": 40}
    _, _, model, _ = procedural.load_for_scoring(run_dir, "final", path=checkpoint)
    assert same_parameters(model, checkpoint)
    # The three files differ, so the comparisons above tell them apart.
    assert not same_parameters(model, layout.final_model)
    assert not same_parameters(model, layout.best_model)
    assert not same_parameters(TD3.load(layout.best_model, device="cpu"), layout.final_model)
    with pytest.raises(ValueError, match="`which` must be one of"):
        procedural.load_for_scoring(run_dir, "newest")


def test_score_run_reports_each_test_set_of_the_run(scripts, run_dir):
    procedural, _ = scripts
    rows, paths = procedural.score_run(run_dir, "td3", ENV_ID, 3, [], 1, n_layouts=2, trajectory_layouts=1, which="best")
    assert [(row["algo"], row["seed"], row["episodes"]) for row in rows] == [("td3", 3, 2)]
    assert 0.0 <= rows[0]["success_rate"] <= 1.0
    assert len(paths) == 1
    assert set(paths[0]["seed"]) == {3}


def test_budget_sweep_scores_a_checkpoint_and_names_configs_files(scripts, run_dir, tmp_path):
    procedural, budget_sweep = scripts
    point = RunLayout(run_dir, ENV_ID).checkpoints()[0]
    row = budget_sweep.score_checkpoint(run_dir, "tiny", 3, point.timesteps, point.model, 2)
    assert (row["config"], row["algo"], row["timesteps"], row["episodes"]) == ("tiny", "td3", point.timesteps, 2)
    inside = ROOT / "benchmarks" / "configs" / "budget_sweep" / "shaping.yml"
    assert procedural.repository_path(str(inside)) == "benchmarks/configs/budget_sweep/shaping.yml"
    outside = tmp_path / "configs.yml"
    assert procedural.repository_path(str(outside)) == str(outside.resolve())
