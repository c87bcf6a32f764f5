"""Options that size memory are bounded: exit 2 naming the option and its range, before a run folder is made."""

import pytest

from sb3_adc.cli.common import key_values
from sb3_adc.config import HyperparamsError, load_hyperparams, schema

LIDAR = "sb3_adc/LidarObstacleCourse-v0"


@pytest.mark.parametrize(
    ("env", "options", "message"),
    [
        (LIDAR, ["--env-kwargs", "n_rays:1000000"], "`n_rays` must be an integer in [1, 4096], got 1000000"),
        (LIDAR, ["--env-kwargs", "speed:1e300"], "`speed` must be in (0, 200] m (MAX_COURSE_SIDE"),
        (LIDAR, ["--env-kwargs", "speed:fast"], "`speed` must be a number, got 'fast' (str)"),
        ("Pendulum-v1", ["-params", "buffer_size:1e12"], "`buffer_size`: expected an integer >= 1, <= 100000000"),
        ("Pendulum-v1", ["-params", "batch_size:1e9"], "`batch_size`: expected an integer >= 1, <= 1000000"),
        ("Pendulum-v1", ["-params", "n_envs:100000"], "`n_envs`: expected an integer >= 1, <= 256"),
        (
            "Pendulum-v1",
            ["-params", "policy_kwargs:dict(net_arch=[200000,200000])"],
            "`policy_kwargs.net_arch`: expected an integer >= 1, <= 16384, got 200000",
        ),
        (
            "Pendulum-v1",
            ["-params", "policy_kwargs:dict(net_arch=dict(pi=[64],qf=[10000,10000,10000]))"],
            "`policy_kwargs.net_arch.qf`: expected at most 100000000 weights between hidden layers",
        ),
    ],
)
def test_sizes_over_their_bound_exit_2_before_writing(cli, train_args, tmp_path, env, options, message):
    logs = tmp_path / "logs"
    status, _, err = cli(*train_args("adc", logs, *options, env=env))
    assert status == 2, err
    assert message in err
    assert "Traceback" not in err
    assert not logs.exists()


def test_replay_buffer_memory_is_bounded_for_the_spaces(cli, train_args, tmp_path, monkeypatch):
    # Pendulum: 3 float32 observations (twice), 1 float32 action and 16 bytes a transition.
    assert schema.replay_buffer_bytes(1000, *pendulum_spaces()) == 1000 * (2 * 12 + 4 + 16)
    monkeypatch.setattr(schema, "MAX_REPLAY_BUFFER_BYTES", 40_000)
    logs = tmp_path / "logs"
    status, _, err = cli(*train_args("adc", logs, "-params", "buffer_size:1000", env="Pendulum-v1"))
    assert status == 2, err
    assert "`buffer_size`: a replay buffer of 1000 transitions of 44 bytes" in err
    assert "accepted: buffer_size <= 909 for these spaces" in err
    assert not logs.exists()


def test_the_lidar_observation_sizes_the_estimate():
    from gymnasium import spaces

    lidar = spaces.Box(0.0, 1.0, (4096,)), spaces.Box(-1.0, 1.0, (1,))
    assert schema.replay_buffer_bytes(3_000_000, *lidar) > schema.MAX_REPLAY_BUFFER_BYTES
    assert schema.replay_buffer_bytes(3_000_000, *lidar, optimize_memory_usage=True) < schema.MAX_REPLAY_BUFFER_BYTES


def pendulum_spaces():
    import gymnasium as gym

    env = gym.make("Pendulum-v1")
    return env.observation_space, env.action_space


def test_command_line_values_read_numbers_as_numbers():
    values = key_values(["speed:1e300", "learning_rate:1e-3", "sizes:[1e3, 2]", "kw:{a: 2.5E+2}", "name:abc"], "--env-kwargs")
    assert values == {"speed": 1e300, "learning_rate": 1e-3, "sizes": [1000.0, 2], "kw": {"a": 250.0}, "name": "abc"}
    assert isinstance(values["speed"], float)


def test_environment_values_may_be_written_as_dict_calls():
    # The RL Zoo's --env-kwargs form; YAML alone would pass the text on as a string.
    items = ["config:dict(observation=dict(cells=64), lanes_count=4)", "name:dict"]
    values = key_values(items, "--env-kwargs", dict_calls=True)
    assert values == {"config": {"observation": {"cells": 64}, "lanes_count": 4}, "name": "dict"}
    assert key_values(["config:dict(a=1)"], "-params") == {"config": "dict(a=1)"}  # -params: the loader reads it
    with pytest.raises(HyperparamsError, match=r"name 'nn.ReLU' is not allowed"):
        key_values(["config:dict(activation_fn=nn.ReLU)"], "--env-kwargs", dict_calls=True)


@pytest.mark.parametrize("net_arch", [[64, 64], {"pi": [64], "qf": [400, 300]}])
def test_ordinary_networks_pass(net_arch):
    config = load_hyperparams("td3", "Pendulum-v1", overrides={"policy_kwargs": {"net_arch": net_arch}})
    assert config.model_kwargs["policy_kwargs"]["net_arch"] == net_arch


def test_layer_sizes_must_be_a_list():
    with pytest.raises(HyperparamsError, match=r"net_arch`: expected a list of layer sizes from 1 to 16384"):
        load_hyperparams("adc", "Pendulum-v1", overrides={"policy_kwargs": {"net_arch": 64}})
