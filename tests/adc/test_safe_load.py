"""
Safe loading of model zips (``load(..., safe=True)``): the file's pickled entries are built from an allow-list, so
a hostile zip runs no code, and the project's own zips (ADC, SB3 TD3) load and predict the same as an ordinary load.
"""

from __future__ import annotations

import io
import os
import pickle
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3 import TD3

from sb3_adc import ADC
from sb3_adc.common.noise import EpsilonGaussianNoise
from sb3_adc.common.safe_load import UnsafeModelFileError, safe_objects


def _model(tmp_path: Path) -> Path:
    env = gym.make("Pendulum-v1")
    noise = EpsilonGaussianNoise(np.zeros(1), 0.1 * np.ones(1), decay_steps=10)
    model = ADC(
        "MlpPolicy",
        env,
        policy_kwargs={"net_arch": [8]},
        learning_starts=10,
        batch_size=8,
        n_steps=2,
        action_noise=noise,
        seed=0,
    )
    model.learn(30)
    path = tmp_path / "adc.zip"
    model.save(path)
    return path


def test_own_zip_loads_safely_and_predicts_the_same(tmp_path: Path) -> None:
    path = _model(tmp_path)
    plain, safe = ADC.load(path), ADC.load(path, safe=True)
    observations = np.random.default_rng(0).uniform(-1, 1, (5, 3)).astype(np.float32)
    np.testing.assert_array_equal(
        plain.predict(observations, deterministic=True)[0], safe.predict(observations, deterministic=True)[0]
    )
    assert safe.observation_space == plain.observation_space
    assert safe.action_space == plain.action_space
    assert type(safe.action_noise) is EpsilonGaussianNoise
    assert safe.lr_schedule(1.0) == plain.lr_schedule(1.0)
    assert safe.replay_buffer_class is plain.replay_buffer_class


def test_sb3_zip_gives_custom_objects_without_unpickling(tmp_path: Path) -> None:
    env = gym.make("Pendulum-v1")
    TD3("MlpPolicy", env, policy_kwargs={"net_arch": [8]}).save(tmp_path / "td3.zip")
    objects = safe_objects(tmp_path / "td3")  # SB3's convention: ".zip" may be left out
    assert isinstance(objects["action_space"], gym.spaces.Box)
    model = TD3.load(tmp_path / "td3.zip", custom_objects=objects)
    assert model.observation_space == env.observation_space


@pytest.mark.parametrize("key", ["action_noise", "lr_schedule", "an_entry_sb3_does_not_know"])
def test_hostile_entry_is_refused_and_runs_nothing(tmp_path: Path, key: str, hostile) -> None:
    path = hostile.zip_with_entry(_model(tmp_path), key, hostile.payload, tmp_path / "hostile.zip")
    with pytest.raises(UnsafeModelFileError, match=rf"`{key}` needs `builtins.exec`") as error:
        ADC.load(path, safe=True)
    assert hostile.marker not in os.environ
    assert "hostile.zip" in str(error.value)
    assert "custom_objects" in str(error.value)
    assert isinstance(error.value, ValueError)
    # Without `safe`, the same file runs its code on load, as SB3's does: what the option is for.
    ADC.load(path)
    assert os.environ.get(hostile.marker) == "ran"


def test_function_shipped_by_value_is_refused(tmp_path: Path, hostile) -> None:
    path = hostile.zip_with_entry(_model(tmp_path), "lr_schedule", lambda _: 1e-3, tmp_path / "lambda.zip")
    with pytest.raises(UnsafeModelFileError, match="lr_schedule"):
        ADC.load(path, safe=True)


def test_custom_objects_replace_a_refused_entry(tmp_path: Path, hostile) -> None:
    path = hostile.zip_with_entry(_model(tmp_path), "action_noise", hostile.payload, tmp_path / "hostile.zip")
    model = ADC.load(path, safe=True, custom_objects={"action_noise": None})
    assert model.action_noise is None
    assert hostile.marker not in os.environ


def test_damaged_entry_and_file_like(tmp_path: Path, hostile) -> None:
    path = _model(tmp_path)
    damaged = hostile.zip_with_serialized(path, "action_space", "not base64!", tmp_path / "damaged.zip")
    with pytest.raises(UnsafeModelFileError, match=r"action_space.*damaged"):
        ADC.load(damaged, safe=True)
    stream = io.BytesIO(path.read_bytes())
    assert ADC.load(stream, safe=True).action_space.shape == (1,)


def test_pickle_protocol_globals_outside_the_list_are_refused(hostile) -> None:
    raw = pickle.dumps(hostile.payload)
    from sb3_adc.common.safe_load import _RestrictedUnpickler

    with pytest.raises(UnsafeModelFileError):
        _RestrictedUnpickler(io.BytesIO(raw)).load()
    assert hostile.marker not in os.environ


def test_vec_normalize_statistics_load_without_running_code(tmp_path: Path, hostile) -> None:
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from sb3_adc.common.safe_load import load_vec_normalize

    venv = DummyVecEnv([lambda: gym.make("Pendulum-v1")])
    saved = VecNormalize(venv)
    saved.reset()
    saved.step(np.zeros((1, 1), dtype=np.float32))
    saved.save(tmp_path / "vecnormalize.pkl")
    loaded = load_vec_normalize(str(tmp_path / "vecnormalize.pkl"), venv)
    np.testing.assert_array_equal(loaded.obs_rms.mean, saved.obs_rms.mean)
    (tmp_path / "hostile.pkl").write_bytes(pickle.dumps(hostile.payload))
    with pytest.raises(UnsafeModelFileError, match=r"builtins\.exec"):
        load_vec_normalize(str(tmp_path / "hostile.pkl"), venv)
    assert hostile.marker not in os.environ


def test_her_replay_buffers_load_without_running_code(tmp_path: Path) -> None:
    """A checkpoint's HER buffer (``replay_buffer_class: HerReplayBuffer``) resumes through the restricted
    unpickler: SB3 drops its environment before pickling, so it holds only the buffer and its goal-selection enum."""
    from stable_baselines3 import HerReplayBuffer
    from stable_baselines3.common.envs import BitFlippingEnv

    from sb3_adc.common.safe_load import REPLAY_BUFFER_GLOBALS, restricted_load

    env = BitFlippingEnv(n_bits=4, continuous=True, max_steps=4)
    kwargs = dict(
        replay_buffer_kwargs=dict(n_sampled_goal=2), learning_starts=20, batch_size=8, policy_kwargs=dict(net_arch=[8])
    )
    model = ADC("MultiInputPolicy", env, replay_buffer_class=HerReplayBuffer, seed=0, **kwargs).learn(60)
    model.save_replay_buffer(tmp_path / "buffer.pkl")
    buffer = restricted_load(str(tmp_path / "buffer.pkl"), REPLAY_BUFFER_GLOBALS, "a replay buffer")
    assert isinstance(buffer, HerReplayBuffer)
    assert buffer.size() == model.replay_buffer.size() == 60
    buffer.set_env(model.get_env())
    assert buffer.sample(8).observations["desired_goal"].shape == (8, 4)
