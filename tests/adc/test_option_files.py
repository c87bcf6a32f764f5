"""ADC's options beyond the paper, as files and the command line meet them: kept by save/load, absent from zips
saved before they existed (their defaults then), taken from hyperparameter entries and ``-params``, and refused
out of range; and training runs with them on."""

from typing import Any

import pytest
import torch as th

from sb3_adc import ADC
from sb3_adc.config import HyperparamsError, load_hyperparams, parse_overrides

# name: (values to set, the defaults, an out-of-range value per option with the error it gives)
OPTIONS: dict[str, tuple[dict[str, Any], dict[str, Any], list[tuple[dict[str, Any], str]]]] = {
    "greedy": (
        {"target_greedy_mix": 0.5, "actor_greedy_weight": 0.125},
        {"target_greedy_mix": 0.0, "actor_greedy_weight": 0.0},
        [
            ({"target_greedy_mix": 2}, r"`target_greedy_mix` must be a number in \[0, 1\], got 2"),
            ({"actor_greedy_weight": -0.5}, "actor_greedy_weight"),
        ],
    ),
    "interval_exploration": (
        {"interval_exploration": 0.25, "interval_temperature": 0.5},
        {"interval_exploration": 0.0, "interval_temperature": 1.0},
        [
            ({"interval_exploration": 2}, r"`interval_exploration` must be a number in \[0, 1\], got 2"),
            ({"interval_temperature": 0}, "interval_temperature"),
        ],
    ),
}


def tiny_model(**kwargs: Any) -> ADC:
    policy_kwargs = dict(net_arch=[16], n_intervals=10)
    return ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=policy_kwargs, learning_starts=50, batch_size=16, seed=0, **kwargs)


@pytest.mark.parametrize("name", OPTIONS)
def test_save_and_load_keep_the_options_and_old_files_get_the_defaults(tmp_path, name):
    values, defaults, _ = OPTIONS[name]
    model = tiny_model(**values)
    model.save(tmp_path / "new.zip")
    loaded = ADC.load(tmp_path / "new.zip")
    assert {key: getattr(loaded, key) for key in values} == values
    for key in values:  # as in a file saved before the options existed
        delattr(model, key)
    model.save(tmp_path / "old.zip")
    loaded = ADC.load(tmp_path / "old.zip")
    assert {key: getattr(loaded, key) for key in defaults} == defaults


@pytest.mark.parametrize("name", OPTIONS)
def test_training_runs_with_the_options(name):
    model = tiny_model(**OPTIONS[name][0]).learn(300)
    assert model._n_updates == 250
    assert all(th.isfinite(parameter).all() for parameter in model.policy.parameters())


@pytest.mark.parametrize("name", OPTIONS)
def test_hyperparameter_entries_and_params_take_the_options_in_range(name):
    values, _, refused = OPTIONS[name]
    overrides = parse_overrides([f"{key}:{value}" for key, value in values.items()])  # -params, as the CLI reads it
    config = load_hyperparams("adc", "Pendulum-v1", None, overrides, 1000)
    assert {key: config.model_kwargs[key] for key in values} == values
    for bad, message in refused:
        with pytest.raises(HyperparamsError, match=message):
            load_hyperparams("adc", "Pendulum-v1", None, bad, 1000)
