"""Loading hyperparameter files: the entry format, resolution into objects, and every error case."""

import os
import textwrap

import pytest
import torch as th
from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise
from stable_baselines3.common.utils import LinearSchedule

import sb3_adc  # noqa: F401 (registers the environments)
from sb3_adc.baselines import DuelingDQNPolicy
from sb3_adc.common.noise import EpsilonGaussianNoise
from sb3_adc.config import (
    ALGORITHMS,
    HyperparamsError,
    check_env_id,
    load_hyperparams,
    parse_overrides,
    read_hyperparams_file,
    resolve_entry,
)
from sb3_adc_envs.wrappers import DiscretizedActions

SOURCE = "my.yml [Pendulum-v1]"


def write(tmp_path, text, name="conf.yml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return str(path)


def adc(entry, n_timesteps=None):
    return resolve_entry("adc", "Pendulum-v1", {"n_timesteps": 1000, "policy": "MlpPolicy", **entry}, SOURCE, n_timesteps)


def test_string_and_mapping_policy_kwargs_resolve_the_same():
    from_string = adc({"policy_kwargs": "dict(net_arch=dict(pi=[30], qf=[30]), activation_fn=nn.Tanh, value_net_arch=[20])"})
    from_mapping = adc(
        {"policy_kwargs": {"net_arch": {"pi": [30], "qf": [30]}, "activation_fn": "nn.Tanh", "value_net_arch": [20]}}
    )
    expected = {"net_arch": {"pi": [30], "qf": [30]}, "activation_fn": th.nn.Tanh, "value_net_arch": [20]}
    assert from_string.model_kwargs["policy_kwargs"] == expected
    assert from_mapping.model_kwargs["policy_kwargs"] == expected


def test_adc_top_level_keys_merge_into_policy_kwargs_and_conflicts_are_errors():
    config = adc({"n_intervals": 60, "aggregation": "max", "policy_kwargs": "dict(net_arch=[64])"})
    assert config.model_kwargs["policy_kwargs"] == {"net_arch": [64], "n_intervals": 60, "aggregation": "max"}
    # The same value in both places is fine, a different one is an error naming both.
    assert adc({"n_intervals": 60, "policy_kwargs": {"n_intervals": 60}}).model_kwargs["policy_kwargs"] == {"n_intervals": 60}
    with pytest.raises(HyperparamsError, match=r"`n_intervals`: conflicts with policy_kwargs n_intervals=100"):
        adc({"n_intervals": 60, "policy_kwargs": {"n_intervals": 100}})
    # Not an ADC key for other algorithms.
    with pytest.raises(HyperparamsError, match="`n_intervals`: unknown key for ddpg"):
        resolve_entry("ddpg", "Pendulum-v1", {"n_timesteps": 10, "policy": "MlpPolicy", "n_intervals": 60}, SOURCE)


def test_policy_options_inside_policy_kwargs_are_checked_where_the_entry_is_read():
    # The same validators as the top-level keys, so that a wrong value never reaches the policy's constructor.
    with pytest.raises(HyperparamsError, match=r"`policy_kwargs\.actor_average_tau`: `actor_average_tau` must be"):
        adc({"policy_kwargs": "dict(net_arch=[64], actor_average_tau=2)"})
    with pytest.raises(HyperparamsError, match=r"`policy_kwargs\.n_intervals`: `n_intervals` must be an integer >= 2"):
        adc({"policy_kwargs": {"n_intervals": 1}})
    assert adc({"policy_kwargs": {"n_intervals": 1e2}}).model_kwargs["policy_kwargs"] == {"n_intervals": 100}

    def td3(policy_kwargs):
        entry = {"n_timesteps": 10, "policy": "MlpPolicy", "policy_kwargs": policy_kwargs}
        return resolve_entry("td3", "Pendulum-v1", entry, SOURCE)

    # TD3's MlpPolicy keeps an averaged actor; its other options (and ADC's) are the policy's to check.
    assert td3({"actor_average_tau": 1e-4}).model_kwargs["policy_kwargs"] == {"actor_average_tau": 1e-4}
    with pytest.raises(HyperparamsError, match=r"`policy_kwargs\.actor_average_tau`: .* got -0\.5"):
        td3({"actor_average_tau": -0.5})
    assert td3({"n_intervals": 1}).model_kwargs["policy_kwargs"] == {"n_intervals": 1}


def test_schedules_and_model_values():
    config = adc({"learning_rate": "lin_1e-3", "critic_learning_rate": 0.002, "train_freq": [1, "episode"], "gamma": 1})
    schedule = config.model_kwargs["learning_rate"]
    assert isinstance(schedule, LinearSchedule)
    assert schedule(1.0) == pytest.approx(1e-3)
    assert schedule(0.25) == pytest.approx(2.5e-4)
    assert config.model_kwargs["critic_learning_rate"] == 0.002
    assert config.model_kwargs["train_freq"] == (1, "episode")
    assert config.model_kwargs["gamma"] == 1.0
    assert isinstance(config.model_kwargs["gamma"], float)


@pytest.mark.parametrize(
    ("noise", "noise_class"),
    [
        ({"noise_type": "normal", "noise_std": 0.2}, NormalActionNoise),
        ({"noise_type": "ornstein-uhlenbeck", "noise_std": [0.2]}, OrnsteinUhlenbeckActionNoise),
        ({"noise_type": "epsilon-normal", "noise_std": 0.2}, EpsilonGaussianNoise),
    ],
)
def test_noise_types(noise, noise_class):
    import gymnasium as gym

    config = adc(noise)
    action_noise = config.make_action_noise(gym.make("Pendulum-v1").action_space)
    assert isinstance(action_noise, noise_class)
    assert action_noise._sigma == pytest.approx([0.2])


def test_epsilon_noise_defaults_are_documented_and_saved():
    config = adc({"noise_type": "epsilon-normal", "noise_std": 0.1, "n_envs": 2}, n_timesteps=4000)
    # Default: half of n_timesteps / n_envs (steps per environment), from 1 to 0.
    assert config.noise.epsilon_decay_steps == 1000
    assert (config.noise.epsilon_initial, config.noise.epsilon_final) == (1.0, 0.0)
    assert config.saved["epsilon_decay_steps"] == 1000
    assert config.saved["n_timesteps"] == 4000
    explicit = adc({"noise_type": "epsilon-normal", "noise_std": 0.1, "epsilon_decay_steps": 7, "epsilon_final": 0.1})
    assert (explicit.noise.epsilon_decay_steps, explicit.noise.epsilon_final) == (7, 0.1)


@pytest.mark.parametrize(
    ("entry", "key", "problem"),
    [
        ({"epsilon_decay_steps": 10}, "epsilon_decay_steps", "only accepted with `noise_type: epsilon-normal`"),
        ({"noise_type": "normal", "noise_std": 0.1, "epsilon_final": 0.1}, "epsilon_final", "only accepted with"),
        ({"noise_std": 0.1}, "noise_std", "needs `noise_type`"),
        ({"noise_type": "normal"}, "noise_std", "required with `noise_type: normal`"),
        ({"noise_type": "gaussian", "noise_std": 0.1}, "noise_type", "'normal', 'ornstein-uhlenbeck', 'epsilon-normal'"),
        ({"noise_type": "normal", "noise_std": -0.1}, "noise_std", "a number >= 0.0"),
        ({"buffer_size": "big"}, "buffer_size", "expected an integer >= 1, <= 100000000, got 'big'"),
        ({"buffer_size": True}, "buffer_size", "expected an integer >= 1, <= 100000000, got True"),
        ({"batch_size": 32.5}, "batch_size", "an integer >= 1"),
        ({"gamma": 1.5}, "gamma", "a number >= 0.0, <= 1.0"),
        ({"tau": "0.01"}, "tau", "a number"),
        ({"learning_rate": "lin_fast"}, "learning_rate", "'lin_<number>'"),
        ({"learning_rate": "exp_0.1"}, "learning_rate", "'lin_<number>'"),
        ({"learning_rate": 0}, "learning_rate", "a number > 0"),
        ({"train_freq": [1, "epoch"]}, "train_freq", '[n, "step" | "episode"]'),
        ({"gradient_steps": 0}, "gradient_steps", "an integer >= 1 or -1"),
        ({"n_intervals": 1}, "n_intervals", "an integer >= 2"),
        ({"aggregation": "sum"}, "aggregation", "'mean', 'max'"),
        ({"actor_average_tau": 1}, "actor_average_tau", "must be a number >= 0 and < 1"),
        ({"actor_average_tau": "small"}, "actor_average_tau", "expected a number, got 'small'"),
        ({"policy_kwargs": [64, 64]}, "policy_kwargs", "a mapping"),
        ({"policy_kwargs": "[64, 64]"}, "policy_kwargs", "must be a mapping"),
        ({"policy_kwargs": "dict(activation_fn=nn.Softmax2d)"}, "policy_kwargs", "name 'nn.Softmax2d' is not allowed"),
        ({"policy_kwargs": {"activation_fn": "os.system"}}, "policy_kwargs.activation_fn", "unknown name 'os.system'"),
        ({"env_kwargs": [1]}, "env_kwargs", "a mapping with string keys"),
        ({"normalize": "yes"}, "normalize", "name 'yes' is not allowed"),
        ({"normalize": {"norm_obs": True, "clip": 5}}, "normalize.clip", "unknown VecNormalize keyword"),
        ({"env_wrapper": "os.system"}, "env_wrapper", "unknown environment wrapper 'os.system'"),
        ({"env_wrapper": [{"gymnasium.wrappers.ClipAction": {}}, "subprocess.call"]}, "env_wrapper", "subprocess.call"),
        ({"callback": "rl_zoo3.callbacks.ParallelTrainCallback"}, "callback", "unknown callback"),
        ({"replay_buffer_class": "my.Buffer"}, "replay_buffer_class", "unknown replay buffer class"),
        ({"policy": "my_module.EvilPolicy"}, "policy", "unknown policy 'my_module.EvilPolicy' for ADC; accepted: CnnPolicy"),
        ({"n_timesteps": "1e5"}, "n_timesteps", "an integer >= 1"),
        ({"learnig_rate": 0.001}, "learnig_rate", "unknown key for adc (ADC); accepted keys:"),
        ({"action_noise": "NormalActionNoise"}, "action_noise", "unknown key"),
        ({"seed": 3}, "seed", "unknown key"),
    ],
)
def test_invalid_values_name_source_key_and_accepted_values(entry, key, problem):
    with pytest.raises(HyperparamsError) as info:
        adc(entry)
    message = str(info.value)
    assert message.startswith(f"{SOURCE}: `{key}`"), message
    assert problem in message


def test_unknown_key_lists_accepted_keys():
    with pytest.raises(HyperparamsError) as info:
        adc({"learnig_rate": 0.001})
    for accepted in ("learning_rate", "critic_learning_rate", "n_intervals", "noise_type", "policy_kwargs", "env_wrapper"):
        assert accepted in str(info.value)


def test_missing_required_keys():
    with pytest.raises(HyperparamsError, match=r"`n_timesteps`: required key missing"):
        resolve_entry("adc", "Pendulum-v1", {"policy": "MlpPolicy"}, SOURCE)
    with pytest.raises(HyperparamsError, match=r"`policy`: required key missing"):
        resolve_entry("adc", "Pendulum-v1", {"n_timesteps": 10}, SOURCE)


def test_unknown_algorithm_lists_the_accepted_ones():
    with pytest.raises(HyperparamsError) as info:
        load_hyperparams("ppo2", "Pendulum-v1")
    assert "unknown algorithm 'ppo2'" in str(info.value)
    for name in ("adc", "ddpg", "dqn", "sac", "td3", "vanilla_ac"):
        assert name in str(info.value)


def test_dqn_entry_resolves_dueling_policy_and_wrapper():
    import gymnasium as gym

    config = resolve_entry(
        "dqn",
        "Pendulum-v1",
        {
            "n_timesteps": 10,
            "policy": "sb3_adc.baselines.DuelingDQNPolicy",
            "env_wrapper": [{"sb3_adc_envs.wrappers.DiscretizedActions": {"n_actions": 7}}],
        },
        SOURCE,
    )
    assert config.model_kwargs["policy"] is DuelingDQNPolicy
    env = config.wrap_env(gym.make("Pendulum-v1"))
    assert isinstance(env, DiscretizedActions)
    assert env.action_space.n == 7
    with pytest.raises(HyperparamsError, match="`noise_type`: unknown key for dqn"):
        resolve_entry("dqn", "Pendulum-v1", {"n_timesteps": 1, "policy": "MlpPolicy", "noise_type": "normal"}, SOURCE)


def test_file_default_entry_is_merged_under_env_entries(tmp_path):
    path = write(
        tmp_path,
        """
        default:
          n_timesteps: !!float 2e4
          policy: MlpPolicy
          gamma: 0.9
        Pendulum-v1:
          gamma: 0.95
          batch_size: 32
        """,
    )
    config = load_hyperparams("adc", "Pendulum-v1", conf_file=path)
    assert config.n_timesteps == 20000
    assert config.model_kwargs["gamma"] == 0.95
    assert config.model_kwargs["batch_size"] == 32
    assert config.source == f"{path} [Pendulum-v1]"
    # An environment without an entry uses `default` alone.
    fallback = load_hyperparams("adc", "MountainCarContinuous-v0", conf_file=path)
    assert fallback.model_kwargs["gamma"] == 0.9
    assert fallback.source == f"{path} [default]"


def test_unknown_env_id_lists_the_file_entries(tmp_path):
    path = write(
        tmp_path,
        "Pendulum-v1: {n_timesteps: 10, policy: MlpPolicy}\nsb3_adc/NoisyPendulum-v1: {n_timesteps: 10, policy: MlpPolicy}\n",
    )
    with pytest.raises(HyperparamsError) as info:
        load_hyperparams("adc", "MountainCarContinuous-v0", conf_file=path)
    assert "no entry for environment 'MountainCarContinuous-v0'" in str(info.value)
    assert "Pendulum-v1, sb3_adc/NoisyPendulum-v1" in str(info.value)
    with pytest.raises(HyperparamsError, match="unknown environment id 'Pendulum-v9'; closest registered ids: Pendulum-v1"):
        check_env_id("Pendulum-v9")
    check_env_id("sb3_adc/NoisyPendulum-v1")


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ("Pendulum-v1:\n  gamma: 0.9\n  gamma: 0.8\n", "duplicate key 'gamma'"),
        ("Pendulum-v1: !!python/object/apply:os.system ['echo pwned']\n", "Python tags are not accepted"),
        ("Pendulum-v1:\n  policy: !!python/name:os.system\n", "Python tags are not accepted"),
        ("Pendulum-v1: [1, 2]\n", "an entry must be a mapping"),
        ("- Pendulum-v1\n", "expected a mapping of environment ids"),
        ("Pendulum-v1: {gamma: [0.9\n", "file is not valid YAML"),
    ],
)
def test_bad_files(tmp_path, text, problem):
    path = write(tmp_path, text)
    with pytest.raises(HyperparamsError, match=problem) as info:
        read_hyperparams_file(path)
    assert path in str(info.value)


def test_missing_file_and_shipped_file_names():
    with pytest.raises(HyperparamsError, match=r"hyperparameter file not found \(nor a shipped file: adc, crossq, ddpg, dqn"):
        load_hyperparams("adc", "Pendulum-v1", conf_file="/nonexistent/adc.yml")
    # A shipped file by name: here ddpg.yml's entry, trained with ADC.
    config = load_hyperparams("adc", "Pendulum-v1", conf_file="ddpg")
    assert config.source.endswith("ddpg.yml [Pendulum-v1]")
    assert "n_intervals" not in config.model_kwargs["policy_kwargs"]


def test_policy_kwargs_attack_in_a_file_names_file_entry_key_and_expression(tmp_path):
    path = write(
        tmp_path,
        """
        Pendulum-v1:
          n_timesteps: 100
          policy: MlpPolicy
          policy_kwargs: "dict(net_arch=[64], activation_fn=__import__('os').system('touch pwned'))"
        """,
    )
    with pytest.raises(HyperparamsError) as info:
        load_hyperparams("adc", "Pendulum-v1", conf_file=path)
    message = str(info.value)
    assert f"{path} [Pendulum-v1]: `policy_kwargs`" in message
    assert "__import__('os').system('touch pwned')" in message
    assert not os.path.exists("pwned")


def test_overrides_are_read_as_yaml_and_validated(tmp_path):
    overrides = parse_overrides(["learning_rate:lin_0.001", "train_freq:[2, episode]", "policy_kwargs:dict(net_arch=[8])"])
    assert overrides == {"learning_rate": "lin_0.001", "train_freq": [2, "episode"], "policy_kwargs": "dict(net_arch=[8])"}
    path = write(tmp_path, "Pendulum-v1: {n_timesteps: 10, policy: MlpPolicy}\n")
    config = load_hyperparams("adc", "Pendulum-v1", conf_file=path, overrides=overrides, n_timesteps=50)
    assert config.model_kwargs["policy_kwargs"] == {"net_arch": [8]}
    assert config.n_timesteps == 50
    with pytest.raises(HyperparamsError, match="key:value"):
        parse_overrides(["learning_rate=0.1"])
    with pytest.raises(HyperparamsError, match="with command-line overrides of gama"):
        load_hyperparams("adc", "Pendulum-v1", conf_file=path, overrides={"gama": 0.9})


def test_saved_config_reloads_to_the_same_experiment():
    config = adc({"learning_rate": "lin_1e-3", "noise_type": "epsilon-normal", "noise_std": 0.1, "train_freq": [1, "step"]})
    reloaded = resolve_entry("adc", "Pendulum-v1", config.saved, "config.yml")
    assert reloaded.saved == config.saved
    assert reloaded.noise == config.noise


def test_user_algorithms_can_be_added():
    from stable_baselines3 import TD3

    class MyTD3(TD3):
        pass

    ALGORITHMS.add("my_td3", MyTD3)
    try:
        config = resolve_entry("my_td3", "Pendulum-v1", {"n_timesteps": 5, "policy": "MlpPolicy", "policy_delay": 3}, SOURCE)
    finally:
        ALGORITHMS.remove("my_td3")
    assert config.algorithm_class is MyTD3
    assert config.model_kwargs["policy_delay"] == 3
    with pytest.raises(HyperparamsError, match="unknown algorithm 'my_td3'"):
        resolve_entry("my_td3", "Pendulum-v1", {"n_timesteps": 5, "policy": "MlpPolicy"}, SOURCE)


def test_overriding_the_noise_type_drops_the_entrys_epsilon_keys(tmp_path):
    """``-params noise_type:normal`` on an entry with epsilon-gated noise replaces the noise, as in the RL Zoo; the
    epsilon keys belong to the noise replaced. Epsilon keys given with the override are still checked."""
    path = write(
        tmp_path,
        """
        Pendulum-v1:
          n_timesteps: 1000
          policy: MlpPolicy
          noise_type: epsilon-normal
          noise_std: 0.5
          epsilon_decay_steps: 500
          epsilon_final: 0.05
        """,
    )
    config = load_hyperparams("ddpg", "Pendulum-v1", str(path), overrides={"noise_type": "normal", "noise_std": 0.1})
    assert (config.noise.noise_type, config.noise.std, config.noise.epsilon_decay_steps) == ("normal", 0.1, 0)
    assert "epsilon_decay_steps" not in config.saved
    # Overrides of other keys keep the entry's noise whole.
    kept = load_hyperparams("ddpg", "Pendulum-v1", str(path), overrides={"noise_std": 0.2})
    assert (kept.noise.noise_type, kept.noise.epsilon_decay_steps, kept.noise.epsilon_final) == ("epsilon-normal", 500, 0.05)
    with pytest.raises(HyperparamsError, match="`epsilon_final`: only accepted with"):
        load_hyperparams("ddpg", "Pendulum-v1", str(path), overrides={"noise_type": "normal", "epsilon_final": 0.1})
