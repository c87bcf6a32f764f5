"""Search spaces and study bookkeeping of :mod:`sb3_adc.experiment.tuning`."""

import multiprocessing
import os
import socket
import subprocess
import sys

import optuna
import pytest

from sb3_adc.config import resolve_entry
from sb3_adc.config.loader import packaged_hyperparams_file, read_hyperparams_file, select_entry
from sb3_adc.experiment import tuning
from sb3_adc.experiment.manager import RunInterrupted
from sb3_adc.experiment.samplers import SAMPLERS, Space
from sb3_adc.experiment.tuning import TuneSettings, tune
from sb3_adc.experiment.tuning_trials import TrialEvalCallback, trial_entry


def journal(settings: TuneSettings) -> optuna.storages.JournalStorage:
    return optuna.storages.JournalStorage(optuna.storages.journal.JournalFileBackend(settings.storage_url()))


def tune_interrupted(settings: TuneSettings, monkeypatch, when) -> None:
    """Fault injection: tune until a trial's evaluation callback, at a step where ``when(callback)``, gets Ctrl-C."""
    on_step = TrialEvalCallback._on_step

    def interrupt(callback):
        if when(callback):
            raise KeyboardInterrupt
        return on_step(callback)

    monkeypatch.setattr(TrialEvalCallback, "_on_step", interrupt)
    with pytest.raises(RunInterrupted):
        tune(settings)
    monkeypatch.setattr(TrialEvalCallback, "_on_step", on_step)


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


def test_trial_of_a_dead_worker_is_failed_and_continued(tiny_study):
    """A trial left running by a killed worker of this machine is marked failed and continued; the budget is met."""
    settings = tiny_study(n_trials=2, seeds=(0,), n_evaluations=1, pruner="median")
    os.makedirs(settings.study_dir)
    storage = journal(settings)
    study = optuna.create_study(storage=storage, study_name=settings.name, direction="maximize")
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True, check=True)
    stale = study.ask({"gamma": optuna.distributions.CategoricalDistribution([0.9, 0.95, 0.98, 0.99])})
    stale.set_user_attr("worker", f"{socket.gethostname()}:{dead.stdout.strip()}")
    result = tune(settings)
    trials = optuna.load_study(study_name=settings.name, storage=storage).trials
    assert trials[0].state == optuna.trial.TrialState.FAIL
    assert [trial.state for trial in trials[1:]].count(optuna.trial.TrialState.FAIL) == 0
    assert result.n_finished == 2
    (continuation,) = [trial for trial in trials if trial.user_attrs.get("continues") == 0]
    assert continuation.params["gamma"] == trials[0].params["gamma"]
    # The stale trial left no runs: the continuation trains in its own folder.
    assert continuation.user_attrs["trial_dir"] == f"trial_{continuation.number}"


def test_interrupted_trial_keeps_its_runs(tmp_path, monkeypatch, capsys, tiny_study):
    """
    Fault injection: Ctrl-C during the second seed of a trial. The next invocation continues the trial with the same
    hyperparameters: the finished seed is not trained again, the other resumes from its checkpoint, and the pruner
    sees every evaluation once.
    """
    settings = tiny_study()
    tune_interrupted(settings, monkeypatch, lambda callback: callback.step_offset == 2 and callback.num_timesteps == 150)
    trial_dir = tmp_path / "tuning" / settings.name / "trial_0"
    first_seed = trial_dir / "seed_0" / "Pendulum-v1.zip"
    trained_at = first_seed.stat().st_mtime_ns
    storage = journal(settings)
    (interrupted,) = optuna.load_study(study_name=settings.name, storage=storage).trials
    assert interrupted.state == optuna.trial.TrialState.FAIL
    assert sorted(interrupted.intermediate_values) == [0, 1, 2]
    capsys.readouterr()

    result = tune(settings)
    output = capsys.readouterr().out
    assert result.n_finished == 1
    _, continuation = optuna.load_study(study_name=settings.name, storage=storage).trials
    assert continuation.state == optuna.trial.TrialState.COMPLETE
    assert continuation.user_attrs["continues"] == 0
    assert continuation.user_attrs["trial_dir"] == "trial_0"
    assert continuation.user_attrs["shipped"]
    assert first_seed.stat().st_mtime_ns == trained_at
    assert "Training ddpg on Pendulum-v1 (seed 0" not in output
    assert f"Resuming {trial_dir / 'seed_1'} from timestep 150 of 200" in output
    assert sorted(continuation.intermediate_values) == [0, 1, 2, 3]
    assert {step: continuation.intermediate_values[step] for step in (0, 1, 2)} == interrupted.intermediate_values
    assert continuation.value == pytest.approx(
        (continuation.user_attrs["return_seed_0"] + continuation.user_attrs["return_seed_1"]) / 2
    )
    assert not list((trial_dir / "seed_1").glob("rl_model_*")), "a finished trial's checkpoints are removed"


def test_continuation_with_a_changed_entry_starts_afresh(monkeypatch, tiny_study):
    """Runs of an interrupted trial are reused only for the same entry: new -params make the continuation retrain."""
    settings = tiny_study(seeds=(0,))
    tune_interrupted(settings, monkeypatch, lambda callback: callback.num_timesteps == 150)
    settings.overrides["batch_size"] = 16
    tune(settings)
    storage = journal(settings)
    _, continuation = optuna.load_study(study_name=settings.name, storage=storage).trials
    assert continuation.user_attrs["continues"] == 0
    assert continuation.user_attrs["trial_dir"] == "trial_1"
    assert continuation.state == optuna.trial.TrialState.COMPLETE


def test_reports_every_evaluation_of_every_seed(tiny_study):
    settings = tiny_study()
    tune(settings)
    storage = journal(settings)
    (trial,) = optuna.load_study(study_name=settings.name, storage=storage).trials
    assert sorted(trial.intermediate_values) == [0, 1, 2, 3]
    assert trial.value == pytest.approx((trial.user_attrs["return_seed_0"] + trial.user_attrs["return_seed_1"]) / 2)


def test_workers_take_the_trials_left_one_at_a_time(tiny_study):
    """A worker runs trials while the shared count has some left, so a free worker takes the next one."""
    settings = tiny_study(seeds=(0,), n_evaluations=1)
    os.makedirs(settings.study_dir)
    tickets = multiprocessing.get_context("spawn").Value("i", 2)
    base = tuning._base_entry(settings)
    tuning._work(settings, base, 0, tickets)
    assert tickets.value == 0
    tuning._work(settings, base, 1, tickets)  # nothing left: runs none
    trials = optuna.load_study(study_name=settings.name, storage=journal(settings)).trials
    assert [trial.state for trial in trials] == [optuna.trial.TrialState.COMPLETE] * 2
