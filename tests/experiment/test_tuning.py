"""Search spaces and study bookkeeping of :mod:`sb3_adc.experiment.tuning`."""

import os
import socket
import subprocess
import sys

import optuna
import pytest

from sb3_adc.config import resolve_entry
from sb3_adc.config.loader import packaged_hyperparams_file, read_hyperparams_file, select_entry
from sb3_adc.experiment.samplers import SAMPLERS, Space
from sb3_adc.experiment.tuning import TuneSettings, trial_entry, tune


@pytest.mark.parametrize("algo", sorted(SAMPLERS))
def test_every_sampled_entry_is_valid(algo):
    """Whatever a sampler draws, the entry it makes passes the same validation as a hyperparameter file."""
    env_id = "Pendulum-v1"
    path = packaged_hyperparams_file(algo)
    base, _ = select_entry(read_hyperparams_file(path), env_id, path)
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0), direction="maximize")
    for _ in range(30):
        trial = study.ask()
        params = SAMPLERS[algo](Space(trial, base))
        assert params, "a sampler draws at least one value"
        config = resolve_entry(algo, env_id, trial_entry(base, params, {}), "test")
        study.tell(trial, 0.0)
        if "gamma" in params:
            assert config.model_kwargs["gamma"] == params["gamma"]


def test_adc_space_covers_its_own_knobs():
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=1))
    seen: dict[str, set] = {"critic_design": set(), "n_intervals": set(), "noise_type": set()}
    for _ in range(40):
        trial = study.ask()
        SAMPLERS["adc"](Space(trial, {"policy_kwargs": "dict(net_arch=[64, 64])", "learning_rate": 1e-3}))
        for key in seen:
            seen[key].add(trial.params[key])
        study.tell(trial, 0.0)
    assert seen["critic_design"] == {"legendre", "state_value", "paper"}
    assert len(seen["n_intervals"]) > 1
    assert seen["noise_type"] == {"normal", "epsilon-normal"}


def test_epsilon_keys_dropped_with_another_noise():
    entry = trial_entry(
        {"noise_type": "epsilon-normal", "epsilon_decay_steps": 100, "gamma": 0.9}, {"noise_type": "normal"}, {}
    )
    assert entry == {"noise_type": "normal", "gamma": 0.9}


def test_interrupted_trial_is_failed_and_replaced(tmp_path):
    """A trial left running by a killed worker of this machine is marked failed; the budget is still met."""
    settings = TuneSettings(
        algo="ddpg",
        env_id="Pendulum-v1",
        n_trials=2,
        n_timesteps=200,
        n_evaluations=1,
        eval_episodes=1,
        final_eval_episodes=1,
        log_folder=str(tmp_path),
        overrides={"learning_starts": 100, "policy_kwargs": {"net_arch": [4]}, "batch_size": 8},
        device="cpu",
    )
    os.makedirs(settings.study_dir)
    storage = optuna.storages.JournalStorage(optuna.storages.journal.JournalFileBackend(settings.storage_url()))
    study = optuna.create_study(storage=storage, study_name=settings.name, direction="maximize")
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True, check=True)
    stale = study.ask()

    stale.set_user_attr("worker", f"{socket.gethostname()}:{dead.stdout.strip()}")
    result = tune(settings)
    states = [trial.state for trial in optuna.load_study(study_name=settings.name, storage=storage).trials]
    assert states[0] == optuna.trial.TrialState.FAIL
    assert states.count(optuna.trial.TrialState.COMPLETE) + states.count(optuna.trial.TrialState.PRUNED) == 2
    assert result.n_finished == 2


def test_reports_every_evaluation_of_every_seed(tmp_path):
    settings = TuneSettings(
        algo="ddpg",
        env_id="Pendulum-v1",
        n_trials=1,
        n_timesteps=200,
        seeds=(0, 1),
        n_evaluations=2,
        eval_episodes=1,
        final_eval_episodes=1,
        pruner="none",
        log_folder=str(tmp_path),
        overrides={"learning_starts": 100, "policy_kwargs": {"net_arch": [4]}, "batch_size": 8},
        device="cpu",
    )
    tune(settings)
    storage = optuna.storages.JournalStorage(optuna.storages.journal.JournalFileBackend(settings.storage_url()))
    (trial,) = optuna.load_study(study_name=settings.name, storage=storage).trials
    assert sorted(trial.intermediate_values) == [0, 1, 2, 3]
    assert trial.value == pytest.approx((trial.user_attrs["return_seed_0"] + trial.user_attrs["return_seed_1"]) / 2)
