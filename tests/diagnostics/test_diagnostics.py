"""Tests of the critic diagnostics (sb3_adc.diagnostics) on TD3, DDPG, SplitRateDDPG and ADC."""

from __future__ import annotations

import copy
import math
import os
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from stable_baselines3 import DDPG, PPO, TD3
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.logger import KVWriter, Logger

from sb3_adc import ADC
from sb3_adc.baselines import SplitRateDDPG
from sb3_adc.diagnostics import (
    ADVANTAGE_PROFILE_KEY,
    EVAL_KEYS,
    GRADIENT_KEYS,
    INTERVAL_KEYS,
    INTERVAL_VISITS_KEY,
    CriticDiagnosticsCallback,
    advantage_roughness,
    batch_diagnostics,
    evaluate_critic,
    gradient_norms,
    interval_visits,
    load_history,
    plot_diagnostics,
)

EPISODE_STEPS = 20


class ConstantRewardEnv(gym.Env):
    """Reward 1 at every step from one constant observation; terminates after ``length`` steps when ``terminate``,
    otherwise runs until a time limit cuts it."""

    def __init__(self, length: int = 10, terminate: bool = False, action_dim: int = 1):
        self.observation_space = spaces.Box(-1.0, 1.0, (1,), dtype=np.float32)
        self.action_space = spaces.Box(-2.0, 2.0, (action_dim,), dtype=np.float32)
        self.length, self.terminate = length, terminate
        self.steps = 0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self.steps = 0
        return np.array([0.5], dtype=np.float32), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        self.steps += 1
        return np.array([0.5], dtype=np.float32), 1.0, self.terminate and self.steps >= self.length, False, {}


def constant_env(length: int = 10, terminate: bool = False, action_dim: int = 1) -> gym.Env:
    env = ConstantRewardEnv(length, terminate, action_dim)
    # Without termination, a time limit truncates the episode at ``length``.
    return env if terminate else gym.wrappers.TimeLimit(env, max_episode_steps=length)


def pendulum() -> gym.Env:
    return gym.make("Pendulum-v1", max_episode_steps=EPISODE_STEPS)


class KeyCollector(KVWriter):
    """A logger output that keeps every value it is given."""

    def __init__(self) -> None:
        self.values: dict[str, Any] = {}

    def write(self, key_values: dict[str, Any], key_excluded: dict[str, tuple[str, ...]], step: int = 0) -> None:
        self.values.update(key_values)


def tiny_model(algo: type, env: gym.Env | str, **kwargs: Any) -> Any:
    policy_kwargs: dict[str, Any] = dict(net_arch=[8])
    if algo is ADC:
        policy_kwargs.update(n_intervals=10, **kwargs.pop("critic_kwargs", {}))
    kwargs = {"learning_starts": 50, "batch_size": 16, "seed": 0, **kwargs}
    return algo("MlpPolicy", env, policy_kwargs=policy_kwargs, **kwargs)


@pytest.mark.parametrize(
    ("algo", "critic_kwargs"),
    [(TD3, {}), (DDPG, {}), (SplitRateDDPG, {}), (ADC, {}), (ADC, {"critic_design": "paper"})],
)
def test_keys_logged_and_history_saved(algo: type, critic_kwargs: dict[str, Any], tmp_path) -> None:
    extra = {"critic_kwargs": critic_kwargs} if algo is ADC else {}
    model = tiny_model(algo, pendulum(), **extra)
    collector = KeyCollector()
    model.set_logger(Logger(folder=None, output_formats=[collector]))
    callback = CriticDiagnosticsCallback(pendulum(), eval_freq=100, n_eval_episodes=2, log_freq=50, save_path=str(tmp_path))
    model.learn(200, callback=callback)
    model.logger.dump(model.num_timesteps)

    expected = {*EVAL_KEYS, *GRADIENT_KEYS}
    interval_keys = set(INTERVAL_KEYS) if algo is ADC else set()
    assert expected | interval_keys <= set(collector.values)
    assert not (set(INTERVAL_KEYS) - interval_keys) & set(collector.values)
    assert all(math.isfinite(collector.values[key]) for key in expected | interval_keys)
    # The buffer fills from the first step, so the batch diagnostics run from the first log time on.
    assert [record["timesteps"] for record in callback.history] == [50, 100, 150, 200]
    assert [record["timesteps"] for record in callback.history if "eval/critic_bias" in record] == [100, 200]
    assert all(record["train/actor_grad_norm"] > 0 for record in callback.history)

    loaded = load_history(str(tmp_path))
    assert [sorted(record) for record in loaded] == [sorted(record) for record in callback.history]
    for saved, original in zip(loaded, callback.history, strict=True):
        for key, value in original.items():
            np.testing.assert_allclose(saved[key], value)
    with open(tmp_path / "critic_diagnostics.csv", encoding="utf-8") as stream:
        header = stream.readline().strip().split(",")
    assert header[0] == "timesteps"
    assert set(header[1:]) == expected | interval_keys
    assert not [name for name in os.listdir(tmp_path) if name.endswith(".partial")]


@pytest.mark.parametrize(
    ("terminate", "tolerance", "used_steps", "n_envs"),
    [
        # Truncated at 10 with gamma 0.5: steps t <= 5 have 0.5^(10 - t) <= 0.05.
        (False, 0.05, list(range(6)), 1),
        # Terminated: every return is exact.
        (True, 0.05, list(range(10)), 2),
        # No step is far enough from the cut: the first step of each episode only.
        (False, 1e-6, [0], 1),
    ],
)
def test_bias_is_q_minus_the_closed_form_return(terminate: bool, tolerance: float, used_steps: list[int], n_envs: int) -> None:
    gamma, length = 0.5, 10
    model = TD3("MlpPolicy", constant_env(length, terminate), gamma=gamma, policy_kwargs=dict(net_arch=[4]), seed=0)
    eval_env = make_vec_env(lambda: constant_env(length, terminate), n_envs=n_envs)
    results = evaluate_critic(model, eval_env, n_eval_episodes=4, truncation_tolerance=tolerance)

    # The observation and the deterministic action never change, so neither does Q.
    obs = np.array([[0.5]], dtype=np.float32)
    action, _ = model.predict(obs, deterministic=True)
    with th.no_grad():
        q = float(model.critic.q1_forward(th.as_tensor(obs), th.as_tensor(model.policy.scale_action(action))))
    steps = np.array(used_steps)
    returns = (1.0 - gamma ** (length - steps)) / (1.0 - gamma)
    assert results["eval/q_mean"] == pytest.approx(q, abs=1e-5)
    assert results["eval/mc_return_mean"] == pytest.approx(returns.mean())
    assert results["eval/critic_bias"] == pytest.approx(q - returns.mean(), abs=1e-5)
    assert results["eval/critic_bias_abs"] == pytest.approx(np.abs(q - returns).mean(), abs=1e-5)
    expected_weight = 0.0 if terminate else float((gamma ** (length - steps)).mean())
    assert results["eval/mc_truncation_weight"] == pytest.approx(expected_weight)


@pytest.mark.parametrize("algo", [TD3, ADC])
def test_gradient_norms_leave_no_gradient_and_no_change(algo: type) -> None:
    model = tiny_model(algo, pendulum(), learning_starts=100)
    model.learn(130)
    model.policy.zero_grad(set_to_none=True)
    parameters = copy.deepcopy(model.policy.state_dict())
    optimizers = [copy.deepcopy(model.actor.optimizer.state_dict()), copy.deepcopy(model.critic.optimizer.state_dict())]
    observations = model.replay_buffer.sample(32).observations

    norms = gradient_norms(model, observations)

    assert all(parameter.grad is None for parameter in model.policy.parameters())
    for name, value in model.policy.state_dict().items():
        assert th.equal(value, parameters[name]), name
    after = [model.actor.optimizer.state_dict(), model.critic.optimizer.state_dict()]
    for before_state, after_state in zip(optimizers, after, strict=True):
        assert [state["step"] for state in before_state["state"].values()] == [
            state["step"] for state in after_state["state"].values()
        ]

    # The same quantities, by an ordinary backward pass on a copy of the model.
    reference = copy.deepcopy(model.policy)
    (-reference.critic.q1_forward(observations, reference.actor(observations)).mean()).backward()
    grad_norm = math.sqrt(sum(float(p.grad.pow(2).sum()) for p in reference.actor.parameters() if p.grad is not None))
    actions = reference.actor(observations).detach().requires_grad_(True)
    reference.critic.q1_forward(observations, actions).sum().backward()
    assert norms["train/actor_grad_norm"] == pytest.approx(grad_norm, rel=1e-5)
    assert norms["train/dq_da_norm"] == pytest.approx(float(actions.grad.norm(dim=1).mean()), rel=1e-5)
    assert norms["train/actor_grad_norm"] > 0


def test_interval_visits_count_every_stored_action() -> None:
    n_intervals, buffer_size, action_dim = 60, 50, 2
    model = ADC(
        "MlpPolicy",
        constant_env(length=7, action_dim=action_dim),
        buffer_size=buffer_size,
        learning_starts=1000,
        policy_kwargs=dict(net_arch=[4], n_intervals=n_intervals),
        seed=0,
    )
    model.learn(80)  # more steps than the buffer holds: it has wrapped around

    counts = interval_visits(model)

    assert counts.shape == (action_dim, n_intervals)
    assert counts.sum() == buffer_size * action_dim
    edges = model.critic.partition.edges.cpu().numpy().astype(np.float64)
    stored = model.replay_buffer.actions.reshape(-1, action_dim)
    for dim in range(action_dim):
        np.testing.assert_array_equal(counts[dim], np.histogram(stored[:, dim], bins=edges)[0])
    results = batch_diagnostics(model, batch_size=8)
    np.testing.assert_array_equal(results[INTERVAL_VISITS_KEY], counts)
    # 50 actions cannot fill 60 intervals per dimension.
    assert results["train/interval_visits_unvisited"] == int((counts == 0).sum()) >= 2 * (n_intervals - buffer_size)
    assert results["train/interval_visits_min_fraction"] == 0.0
    assert results[ADVANTAGE_PROFILE_KEY].shape[-1] == n_intervals
    np.testing.assert_allclose(results[ADVANTAGE_PROFILE_KEY].sum(axis=-1), 0.0, atol=1e-5)


def test_advantage_roughness() -> None:
    generator = th.Generator().manual_seed(0)
    n = 16
    constant = th.randn(32, 2, 1, generator=generator).expand(32, 2, n)
    assert advantage_roughness(constant) == {"train/advantage_neighbour_diff": 0.0, "train/advantage_roughness": 0.0}

    # A linear profile: mean |step| = slope, std over the intervals = slope * sqrt((n^2 - 1) / 12).
    linear = 3.0 * th.arange(n, dtype=th.float32).expand(4, 1, n)
    linear_results = advantage_roughness(linear)
    assert linear_results["train/advantage_neighbour_diff"] == pytest.approx(3.0)
    assert linear_results["train/advantage_roughness"] == pytest.approx(math.sqrt(12.0 / (n**2 - 1)), rel=1e-5)

    noise = th.randn(64, 1, n, generator=generator)
    noise_roughness = advantage_roughness(noise)["train/advantage_roughness"]
    assert noise_roughness > 5 * linear_results["train/advantage_roughness"]
    # Scale-free, and blind to a constant offset.
    assert advantage_roughness(7.0 * noise + 2.0)["train/advantage_roughness"] == pytest.approx(noise_roughness, rel=1e-5)


def synthetic_history(seed: int, with_intervals: bool) -> list[dict[str, Any]]:
    rng = np.random.default_rng(seed)
    history: list[dict[str, Any]] = []
    for step in (100, 200, 300):
        record: dict[str, Any] = {"timesteps": step, "train/actor_grad_norm": float(rng.uniform(0.1, 2.0))}
        if step != 100:
            record["eval/critic_bias"] = float(rng.normal())
        if with_intervals:
            record[INTERVAL_VISITS_KEY] = rng.integers(0, 50, size=(1, 10))
            record[ADVANTAGE_PROFILE_KEY] = rng.normal(size=(1, 10))
        history.append(record)
    return history


@pytest.mark.parametrize("with_adc", [True, False])
def test_plot_written(with_adc: bool, tmp_path) -> None:
    histories: dict[str, Any] = {"TD3": [synthetic_history(0, False), synthetic_history(1, False)]}
    if with_adc:
        histories["ADC"] = synthetic_history(2, True)
    path = plot_diagnostics(histories, str(tmp_path / "diagnostics.png"), reps=100)
    with open(path, "rb") as stream:
        assert stream.read(8) == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"eval_freq": 0}, "eval_freq"),
        ({"n_eval_episodes": -1}, "n_eval_episodes"),
        ({"log_freq": 1.5}, "log_freq"),
        ({"batch_size": 0}, "batch_size"),
        ({"truncation_tolerance": 0.0}, "truncation_tolerance"),
        ({"truncation_tolerance": 1.5}, "truncation_tolerance"),
    ],
)
def test_invalid_options_name_the_parameter(kwargs: dict[str, Any], name: str) -> None:
    with pytest.raises(ValueError, match=f"`{name}`"):
        CriticDiagnosticsCallback(pendulum(), **kwargs)


def test_evaluate_critic_checks_its_options() -> None:
    model = tiny_model(TD3, pendulum())
    with pytest.raises(ValueError, match="`truncation_tolerance`"):
        evaluate_critic(model, pendulum(), truncation_tolerance=-0.1)
    with pytest.raises(ValueError, match="`n_eval_episodes`"):
        evaluate_critic(model, pendulum(), n_eval_episodes=0)


def test_models_outside_the_td3_family_are_refused() -> None:
    callback = CriticDiagnosticsCallback(pendulum())
    with pytest.raises(TypeError, match="TD3-family"):
        callback.init_callback(PPO("MlpPolicy", pendulum(), n_steps=64))
    with pytest.raises(TypeError, match="dueling interval critic"):
        interval_visits(tiny_model(TD3, pendulum()))
