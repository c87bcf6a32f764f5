"""NaN and inf: a run stops at the first one with an error naming the step and the source, and saves nothing after it."""

import math

import gymnasium as gym
import numpy as np
import optuna
import pytest
import torch as th
from gymnasium import spaces

from sb3_adc import ADC
from sb3_adc.cli import main
from sb3_adc.experiment import TrainSettings, resume, train
from sb3_adc.experiment.callbacks import CheckpointSaver
from sb3_adc.experiment.divergence import FiniteCheck, NonFiniteValue, NonFiniteWeights, TrainingDiverged
from sb3_adc.experiment.layout import RunLayout
from sb3_adc.experiment.tuning import TuneSettings, tune

ENV_ID = "tests/NonFiniteAt-v0"


class NonFiniteAt(gym.Env):
    """
    Random observations and a quadratic cost; at its ``at``-th step (counted across episodes) the environment
    returns NaN in an observation or inf as the reward.
    """

    observation_space = spaces.Box(-1.0, 1.0, (3,), np.float32)
    action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)

    def __init__(self, at: int = 10**9, source: str = "observation"):
        self.at = at
        self.source = source
        self.steps = 0

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        return self.np_random.uniform(-1, 1, 3).astype(np.float32), {}

    def step(self, action):
        self.steps += 1
        observation = self.np_random.uniform(-1, 1, 3).astype(np.float32)
        reward = -float(np.square(action).sum())
        if self.steps == self.at:
            if self.source == "observation":
                observation[1] = np.nan
            else:
                reward = math.inf
        return observation, reward, False, False, {}


if ENV_ID not in gym.registry:
    gym.register(ENV_ID, entry_point=NonFiniteAt)


@pytest.fixture(scope="session")
def run_settings(tiny_settings):
    """``make(folder, **env_kwargs)``: a tiny ADC run on :data:`ENV_ID` with these keywords, a checkpoint every 50 steps."""

    def make(folder, **env_kwargs) -> TrainSettings:
        return tiny_settings(folder, env_id=ENV_ID, seed=0, env_kwargs=env_kwargs, save_freq=50, keep_checkpoints=5)

    return make


@pytest.mark.parametrize(("source", "found"), [("observation", "nan in its observation"), ("reward", "inf in its reward")])
def test_a_non_finite_value_stops_the_run_and_keeps_the_last_good_checkpoint(tmp_path, source, found, run_settings):
    with pytest.raises(TrainingDiverged) as info:
        train(run_settings(tmp_path, at=130, source=source))
    error = info.value
    run_dir = tmp_path / "logs" / "adc" / "tests-NonFiniteAt-v0_1"
    assert (error.timesteps, error.source, error.last_checkpoint) == (130, source, 100)
    message = str(error)
    assert f"training diverged at timestep 130: the training environment returned {found}" in message
    assert "the last good checkpoint (timestep 100) is kept" in message
    assert f"sb3-adc train --resume {run_dir}" in message
    # Nothing was saved after the NaN: no final model, evaluation or checkpoint, and the last checkpoint is finite.
    layout = RunLayout(str(run_dir), ENV_ID)
    assert [checkpoint.timesteps for checkpoint in layout.checkpoints()] == [50, 100]
    assert not (run_dir / "tests-NonFiniteAt-v0.zip").exists()
    assert not layout.is_finished()
    model = ADC.load(layout.checkpoint(100).model)
    assert all(bool(th.isfinite(parameter).all()) for parameter in model.policy.parameters())


def test_the_cli_exits_1_with_the_message_and_resume_continues_from_the_good_checkpoint(tmp_path, capsys, tiny_conf):
    conf = str(tiny_conf / "adc.yml")
    args = ["train", "--algo", "adc", "--env", ENV_ID, "-conf", conf, "-f", str(tmp_path / "logs"), "--seed", "0"]
    args += ["--eval-freq", "100", "--eval-episodes", "1", "--final-eval-episodes", "1", "--no-progress-bar"]
    args += ["--env-kwargs", "at:130", "--device", "cpu"]
    assert main(args) == 1
    captured = capsys.readouterr()
    assert "sb3-adc train: error: training diverged at timestep 130: the training environment returned nan" in captured.err
    assert "Continue with" not in captured.out
    assert "mean return" not in captured.out
    run_dir = tmp_path / "logs" / "adc" / "tests-NonFiniteAt-v0_1"
    assert f"sb3-adc train --resume {run_dir}" in captured.err
    # The resumed run starts from the checkpoint at 100 with new environments, whose 130th step (timestep 230)
    # returns NaN again: stopped again, with the progress up to the checkpoint at 200 kept.
    with pytest.raises(TrainingDiverged) as info:
        resume(str(run_dir))
    assert "Resuming" in capsys.readouterr().out
    assert (info.value.timesteps, info.value.last_checkpoint) == (230, 200)


def test_a_checkpoint_with_non_finite_weights_is_refused(tmp_path):
    layout = RunLayout(str(tmp_path), "Pendulum-v1")
    model = ADC("MlpPolicy", "Pendulum-v1", learning_starts=10, policy_kwargs={"net_arch": [4]}, device="cpu")
    saver = CheckpointSaver(layout, every=10, keep=2)
    saver.init_callback(model)
    assert saver.save().timesteps == 0
    with th.no_grad():
        model.policy.actor.mu[0].weight[0, 0] = math.nan
    with pytest.raises(NonFiniteWeights, match=r"actor\.mu\.0\.weight"):
        saver.save()
    assert [checkpoint.timesteps for checkpoint in layout.checkpoints()] == [0]
    assert sorted(path.name for path in tmp_path.iterdir()) == [
        "rl_model_0_steps.zip",
        "rl_model_manifest_0_steps.json",
        "rl_model_replay_buffer_0_steps.pkl",
    ]


def test_a_nan_action_is_named_as_the_policys_output():
    env = FiniteCheck(ADC("MlpPolicy", "Pendulum-v1", device="cpu").get_env(), "training")
    env.reset()
    with pytest.raises(NonFiniteValue, match="the model's action holds nan") as info:
        env.step(np.array([[np.nan]], dtype=np.float32))
    assert info.value.source == "action"


def tune_settings(tmp_path, **env_kwargs) -> TuneSettings:
    return TuneSettings(
        algo="ddpg",
        env_id=ENV_ID,
        n_trials=1,
        n_timesteps=200,
        seeds=(0,),
        n_evaluations=2,
        eval_episodes=1,
        final_eval_episodes=1,
        pruner="none",
        log_folder=str(tmp_path),
        env_kwargs={"max_episode_steps": 50, **env_kwargs},
        overrides={"learning_starts": 50, "policy_kwargs": {"net_arch": [4]}, "batch_size": 8, "normalize": True},
        device="cpu",
    )


def trial_states(settings: TuneSettings) -> list[str]:
    storage = optuna.storages.JournalStorage(optuna.storages.journal.JournalFileBackend(settings.storage_url()))
    return [trial.state.name for trial in optuna.load_study(study_name=settings.name, storage=storage).trials]


def test_tuning_evaluates_normalized_runs_through_the_nan_check(tmp_path):
    # The trial's own evaluation environment is wrapped as the training one (SB3 syncs VecNormalize through both).
    settings = tune_settings(tmp_path)
    assert tune(settings).n_finished == 1
    assert trial_states(settings) == ["COMPLETE"]


def test_a_diverging_trial_is_pruned_not_an_error_of_the_study(tmp_path):
    settings = tune_settings(tmp_path, at=130, source="reward")
    with pytest.raises(RuntimeError, match=r"no trial of study .* completed"):
        tune(settings)
    assert trial_states(settings) == ["PRUNED"]


def test_critic_diagnostics_evaluate_in_a_checked_run(tmp_path, run_settings):
    # The diagnostics callback builds a plain evaluation env; it must not be synced against the checked training env.
    run = run_settings(tmp_path)
    run.overrides = {
        "callback": {
            "sb3_adc.diagnostics.CriticDiagnosticsCallback": {
                "eval_env": "Pendulum-v1",
                "eval_freq": 100,
                "log_freq": 100,
                "n_eval_episodes": 1,
                "save_path": str(tmp_path / "diagnostics"),
            }
        }
    }
    run.env_id = "Pendulum-v1"
    run.n_timesteps = 200
    train(run)
    history = np.load(tmp_path / "diagnostics" / "critic_diagnostics.npz")
    assert list(history["timesteps"]) == [100, 200]


def test_enjoy_stops_at_a_nan_with_exit_status_1(tmp_path, capsys, run_settings):
    result = train(run_settings(tmp_path, at=10**6))
    config = tmp_path / "logs" / "adc" / "tests-NonFiniteAt-v0_1" / "tests-NonFiniteAt-v0" / "config.yml"
    config.write_text(config.read_text().replace("at: 1000000", "at: 20"))
    assert main(["enjoy", "--run-dir", result.run_dir, "--env", ENV_ID, "-n", "1"]) == 1
    assert "sb3-adc enjoy: error: the evaluation environment returned nan in its observation" in capsys.readouterr().err
