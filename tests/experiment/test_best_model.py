"""
``best_model_metric``: ``best_model.zip`` chosen by the success rate of evaluations made on the same episodes, and
the evaluation history keeping each evaluation's successes (across a resume too).
"""

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.vec_env import DummyVecEnv

from sb3_adc.experiment import TrainSettings, train
from sb3_adc.experiment.callbacks import EvaluationHistory, PeriodicEvalCallback
from sb3_adc.experiment.layout import RunLayout
from sb3_adc.experiment.results import evaluation_rows
from sb3_adc.experiment.settings import SettingsError

pytest.importorskip("pybullet")

#: ADC with a handful of units that never updates (learning starts after the budget): every periodic evaluation
#: evaluates the same policy.
FROZEN = {
    "learning_starts": 1000,
    "batch_size": 16,
    "buffer_size": 1000,
    "policy_kwargs": "dict(net_arch=[8], value_net_arch=[4])",
}


def frozen_run(tmp_path, metric):
    settings = TrainSettings(
        algo="adc",
        env_id="sb3_adc/LidarObstacleCourse-v1",
        overrides=dict(FROZEN),
        env_kwargs={"max_episode_steps": 40},
        n_timesteps=300,
        eval_freq=100,
        eval_episodes=3,
        final_eval_episodes=1,
        run_dir=str(tmp_path / metric),
        device="cpu",
        progress_bar=False,
        best_model_metric=metric,
    )
    train(settings)
    return EvaluationHistory.load(str(tmp_path / metric / "evaluations.npz"))


def test_success_metric_evaluates_every_model_on_the_same_episodes(tmp_path):
    history = frozen_run(tmp_path, "success")
    assert history.timesteps == [100, 200, 300]
    assert len(history.successes) == 3
    assert all(len(row) == 3 for row in history.successes)
    # The same policy on the same layouts and starts: the same episodes.
    assert history.results[0] == history.results[1] == history.results[2]
    assert (tmp_path / "success" / "best_model.zip").is_file()
    # SB3's rule (control): the evaluation environment goes on, so the same policy meets other layouts.
    other = frozen_run(tmp_path, "return")
    assert not other.results[0] == other.results[1] == other.results[2]


def test_best_model_is_the_highest_success_rate_then_the_highest_return():
    env = DummyVecEnv([lambda: gym.make("Pendulum-v1")])
    callback = PeriodicEvalCallback(env, 10, EvaluationHistory(), 2, "unused", best_model_metric="success")
    chosen = []
    for successes, mean_return in [([1, 0], -5.0), ([1, 0], -10.0), ([1, 0], -1.0), ([0, 0], 100.0), ([1, 1], -100.0)]:
        callback._is_success_buffer = [bool(value) for value in successes]
        callback.last_mean_reward = mean_return
        chosen.append(callback._improved(-np.inf))
    assert chosen == [True, False, True, False, True]
    callback._is_success_buffer = []
    with pytest.raises(ValueError, match="info\\['is_success'\\]"):
        callback._improved(-np.inf)
    env.close()


def test_a_resumed_run_keeps_the_successes_and_the_best_so_far(tmp_path):
    history = EvaluationHistory(
        timesteps=[10, 20, 30],
        results=[[1.0, 3.0], [5.0, 5.0], [0.0, 0.0]],
        ep_lengths=[[5, 5], [5, 5], [5, 5]],
        successes=[[True, False], [True, False], [False, False]],
    )
    path = str(tmp_path / "evaluations.npz")
    history.until(20).save(path)
    loaded = EvaluationHistory.load(path)
    assert loaded.successes == [[True, False], [True, False]]
    assert loaded.success_rates() == [0.5, 0.5]
    env = DummyVecEnv([lambda: gym.make("Pendulum-v1")])
    callback = PeriodicEvalCallback(env, 10, loaded, 2, str(tmp_path), best_model_metric="success")
    assert callback.best_success == (0.5, 5.0)
    assert callback.evaluations_successes == loaded.successes
    # An evaluation whose episodes reported no success has no rate (not 0, nor numpy's NaN of an empty mean) and
    # cannot be the best.
    partial = EvaluationHistory(timesteps=[10, 20], results=[[9.0], [1.0]], ep_lengths=[[5], [5]], successes=[[], [False]])
    assert partial.success_rates() == [None, 0.0]
    assert PeriodicEvalCallback(env, 10, partial, 1, str(tmp_path), best_model_metric="success").best_success == (0.0, 1.0)
    env.close()


def test_evaluation_tables_report_each_evaluations_success_rate(tmp_path):
    layout = RunLayout(str(tmp_path), "Pendulum-v1")
    EvaluationHistory(
        timesteps=[10, 20],
        results=[[1.0, 3.0], [5.0, 5.0]],
        ep_lengths=[[5, 5], [5, 5]],
        successes=[[True, False], [True, True]],
    ).save(layout.evaluations)
    assert [row["success_rate"] for row in evaluation_rows(layout, "adc", 0)] == [0.5, 1.0]
    # Episodes that report no success leave the column empty rather than 0.
    EvaluationHistory(timesteps=[10], results=[[1.0]], ep_lengths=[[5]]).save(layout.evaluations)
    assert [row["success_rate"] for row in evaluation_rows(layout, "adc", 0)] == [None]


def test_a_history_with_fewer_rows_of_successes_loads_without_them(tmp_path):
    """Runs resumed by earlier versions lost the successes before their checkpoint: the rows no longer line up."""
    path = tmp_path / "evaluations.npz"
    np.savez(path, timesteps=[10, 20], results=[[1.0], [2.0]], ep_lengths=[[5], [5]], successes=[[True]])
    history = EvaluationHistory.load(str(path))
    assert history.timesteps == [10, 20]
    assert history.successes == []


def test_an_unknown_metric_names_the_setting_and_the_choices():
    with pytest.raises(SettingsError, match="`best_model_metric` must be one of return, success, got 'accuracy'"):
        TrainSettings(algo="adc", env_id="Pendulum-v1", best_model_metric="accuracy")
