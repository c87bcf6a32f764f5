"""AveragedActorTD3: SB3's TD3 update for update without ``actor_average_tau``; with it, the averaged actor of ADC
(the rule per training call, unchanged learning, SB3 files; which predictions use the average and saving it are
tested with ADC's in tests/adc/test_actor_average.py, refusing ADC files with the other baselines in
tests/adc/test_model_files.py), and the ``td3`` name's class."""

import numpy as np
import pytest
import torch as th
from stable_baselines3 import DDPG, TD3
from stable_baselines3.common.logger import configure
from stable_baselines3.td3.policies import TD3Policy

from sb3_adc.baselines import AveragedActorTD3, SplitRateDDPG
from sb3_adc.common.actor_average import ActorAverageTD3Policy, actor_average_weight
from sb3_adc.config.algorithms import get_algorithm

NET = dict(net_arch=[8])
SETTINGS = dict(learning_starts=50, batch_size=16, seed=5, target_policy_noise=0.2, target_noise_clip=0.5)


def make(algorithm=AveragedActorTD3, actor_average_tau=0.0, **kwargs):
    policy_kwargs = {**NET, "actor_average_tau": actor_average_tau} if actor_average_tau else dict(NET)
    return algorithm("MlpPolicy", "Pendulum-v1", policy_kwargs=policy_kwargs, **{**SETTINGS, **kwargs})


def vector(module):
    return th.nn.utils.parameters_to_vector(module.parameters()).detach().clone()


def assert_same_learning(reference, model):
    reference_state, state = reference.policy.state_dict(), model.policy.state_dict()
    assert set(state) - set(reference_state) == {name for name in state if name.startswith("actor_average.")}
    for name, tensor in reference_state.items():
        assert th.equal(tensor, state[name]), name
    size = reference.replay_buffer.size()
    assert size == model.replay_buffer.size() > 0
    np.testing.assert_array_equal(reference.replay_buffer.actions[:size], model.replay_buffer.actions[:size])


def test_the_td3_name_trains_this_class():
    assert get_algorithm("td3") is AveragedActorTD3
    assert issubclass(AveragedActorTD3, TD3)


@pytest.mark.parametrize("gradient_steps", [1, 3])
def test_without_the_option_it_is_sb3s_td3_update_for_update(gradient_steps):
    sb3 = make(TD3, train_freq=gradient_steps, gradient_steps=gradient_steps).learn(200)
    ours = make(train_freq=gradient_steps, gradient_steps=gradient_steps).learn(200)
    assert type(ours.policy) is ActorAverageTD3Policy
    assert ours.policy.actor_average is None
    assert_same_learning(sb3, ours)


def test_the_average_does_not_change_what_is_learned():
    # Target-policy smoothing draws from torch's generator at every update: building the average must not move it.
    assert_same_learning(make(TD3).learn(300), make(actor_average_tau=0.05).learn(300))


@pytest.mark.parametrize(
    ("tau", "policy_delay", "gradient_steps"),
    [(1e-3, 2, 1), (0.4, 1, 1), (0.4, 2, 1), (1e-3, 2, 3), (0.3, 1, 4)],
    ids=["plain-mean", "exponential", "exponential-delayed", "mean-per-call", "exponential-per-call"],
)
def test_each_call_that_updates_the_actor_moves_the_average_by_its_updates(tau, policy_delay, gradient_steps):
    model = make(actor_average_tau=tau, policy_delay=policy_delay).learn(80)
    model.set_logger(configure(None, []))
    moved = 0
    for _ in range(2 * policy_delay):
        average = vector(model.policy.actor_average)
        n_before = model._n_updates // policy_delay
        model.train(gradient_steps=gradient_steps, batch_size=16)
        n_after = model._n_updates // policy_delay
        if n_after == n_before:
            # No actor update in this call: the average stays.
            th.testing.assert_close(vector(model.policy.actor_average), average, rtol=0, atol=0)
            continue
        moved += 1
        weight = actor_average_weight(tau, n_after, n_after - n_before)
        th.testing.assert_close(vector(model.policy.actor_average), (1 - weight) * average + weight * vector(model.actor))
    assert moved > 0
    assert not th.allclose(vector(model.policy.actor_average), vector(model.actor))


@pytest.mark.parametrize("gradient_steps", [1, 3])
def test_split_rate_ddpg_with_an_averaged_actor_learns_what_sb3_ddpg_learns(gradient_steps):
    """The average is only deployed: the actor, critic, targets and the actions taken are SB3's DDPG's."""
    kwargs = {"learning_starts": 50, "batch_size": 16, "buffer_size": 1000, "seed": 3}
    kwargs |= {"train_freq": gradient_steps, "gradient_steps": gradient_steps}
    theirs = DDPG("MlpPolicy", "Pendulum-v1", policy_kwargs=NET, **kwargs).learn(150)
    ours = SplitRateDDPG("MlpPolicy", "Pendulum-v1", policy_kwargs={**NET, "actor_average_tau": 0.05}, **kwargs)
    assert_same_learning(theirs, ours.learn(150))
    assert not th.allclose(vector(ours.policy.actor_average), vector(ours.actor))


def test_the_weight_of_one_update_is_max_tau_and_one_over_n_and_of_several_their_compound():
    assert actor_average_weight(1e-4, 1) == 1.0
    assert actor_average_weight(1e-4, 2_000) == 1 / 2_000
    assert actor_average_weight(1e-4, 50_000) == 1e-4  # exactly tau, as ADC has always weighed one update
    assert actor_average_weight(0.1, 8, n_new=4) == 0.5  # the plain mean: 4 of 8 iterates
    assert actor_average_weight(0.1, 400, n_new=4) == pytest.approx(1 - 0.9**4)  # four EMA steps of one actor
    for n_new in (0, 9):
        with pytest.raises(ValueError, match="`n_new` must be between 1 and `n_actor_updates` \\(8\\)"):
            actor_average_weight(0.1, 8, n_new=n_new)


def test_a_model_file_saved_by_sb3s_td3_loads_and_trains(tmp_path):
    sb3 = make(TD3).learn(100)
    sb3.save(tmp_path / "sb3.zip")
    loaded = AveragedActorTD3.load(tmp_path / "sb3.zip", env=sb3.get_env())
    assert type(loaded.policy) is TD3Policy
    th.testing.assert_close(vector(loaded.actor), vector(sb3.actor), rtol=0, atol=0)
    loaded.learn(60, reset_num_timesteps=False)
    assert loaded._n_updates > sb3._n_updates


@pytest.mark.parametrize("value", [-0.1, 1.0, "0.1"])
def test_invalid_values_name_the_option(value):
    with pytest.raises(ValueError, match=r"`actor_average_tau` must be a number >= 0 and < 1"):
        make(actor_average_tau=value)
