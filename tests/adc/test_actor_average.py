"""ADCPolicy's averaged actor (``actor_average_tau``): the averaging rule, that it leaves learning unchanged, which
predictions use it, and that it survives saving, loading and further training (the last two also for
AveragedActorTD3 and SplitRateDDPG, whose policies keep the same average; their rule per training call is tested
in tests/baselines/test_averaged_actor_td3.py)."""

import numpy as np
import pytest
import torch as th
from stable_baselines3.common.logger import configure

from sb3_adc import ADC
from sb3_adc.adc.policies import ADCPolicy
from sb3_adc.baselines import AveragedActorTD3, SplitRateDDPG
from sb3_adc.common.actor_average import actor_average_weight, check_actor_average_tau

NET = dict(net_arch=[8], n_intervals=4, value_net_arch=[4])
#: The networks of each algorithm whose policy keeps the average.
NETS = {ADC: NET, AveragedActorTD3: dict(net_arch=[8]), SplitRateDDPG: dict(net_arch=[8])}


def make(actor_average_tau=0.0, policy_delay=2, seed=3, learning_starts=50, algorithm=ADC, **kwargs):
    net = NETS[algorithm]
    policy_kwargs = {**net, "actor_average_tau": actor_average_tau} if actor_average_tau else dict(net)
    if algorithm is not SplitRateDDPG:  # DDPG updates its actor at every step
        kwargs["policy_delay"] = policy_delay
    return algorithm(
        "MlpPolicy",
        "Pendulum-v1",
        learning_starts=learning_starts,
        batch_size=16,
        seed=seed,
        policy_kwargs=policy_kwargs,
        **kwargs,
    )


def vector(module):
    return th.nn.utils.parameters_to_vector(module.parameters()).detach().clone()


def test_without_the_option_there_is_no_average():
    model = make()
    assert model.policy.actor_average is None
    assert not any(name.startswith("actor_average") for name in model.policy.state_dict())


def test_the_first_actor_update_copies_the_actor():
    model = make(actor_average_tau=0.01, policy_delay=1, learning_starts=10)
    before = vector(model.policy.actor_average)
    th.testing.assert_close(before, vector(model.actor))  # built as a copy of the initial actor
    model.learn(11)
    assert model._n_updates == 1
    th.testing.assert_close(vector(model.policy.actor_average), vector(model.actor), rtol=0, atol=0)
    assert not th.equal(vector(model.actor), before)


@pytest.mark.parametrize(
    ("tau", "policy_delay"),
    [(1e-3, 1), (1e-3, 2), (0.4, 1), (0.4, 3)],
    ids=["plain-mean", "plain-mean-delayed", "exponential", "exponential-delayed"],
)
def test_each_actor_update_moves_the_average_by_max_tau_and_one_over_n(tau, policy_delay):
    model = make(actor_average_tau=tau, policy_delay=policy_delay).learn(80)
    for _ in range(2 * policy_delay):
        average = vector(model.policy.actor_average)
        model.train(gradient_steps=1, batch_size=16)
        actor = vector(model.actor)
        if model._n_updates % policy_delay:
            # No actor update at this gradient step: the average stays.
            th.testing.assert_close(vector(model.policy.actor_average), average, rtol=0, atol=0)
            continue
        weight = max(tau, 1 / (model._n_updates // policy_delay))
        th.testing.assert_close(vector(model.policy.actor_average), (1 - weight) * average + weight * actor)
    assert not th.allclose(vector(model.policy.actor_average), vector(model.actor))


def test_the_average_does_not_change_what_is_learned():
    # Target-policy smoothing draws from torch's generator at every update: building the average must not move it.
    smoothing = dict(target_policy_noise=0.2, target_noise_clip=0.5)
    plain = make(**smoothing).learn(300)
    averaged = make(actor_average_tau=0.05, **smoothing).learn(300)
    plain_state, averaged_state = plain.policy.state_dict(), averaged.policy.state_dict()
    assert set(averaged_state) - set(plain_state) == {name for name in averaged_state if name.startswith("actor_average.")}
    for name, tensor in plain_state.items():
        assert th.equal(tensor, averaged_state[name]), name
    size = plain.replay_buffer.size()
    np.testing.assert_array_equal(plain.replay_buffer.actions[:size], averaged.replay_buffer.actions[:size])


@pytest.mark.parametrize("algorithm", [ADC, AveragedActorTD3, SplitRateDDPG])
def test_deterministic_predictions_use_the_average_until_it_is_dropped(algorithm):
    model = make(actor_average_tau=0.05, algorithm=algorithm).learn(300)
    observations = np.random.default_rng(0).uniform(-1, 1, size=(5, 3)).astype(np.float32)
    with th.no_grad():
        tensor = th.as_tensor(observations)
        # The actors' outputs are in [-1, 1]; predict returns actions in the environment's units.
        average = model.policy.actor_average(tensor).numpy()
        actor = model.actor(tensor).numpy()
    assert np.abs(average - actor).max() > 1e-3
    deterministic, _ = model.predict(observations, deterministic=True)
    stochastic, _ = model.predict(observations, deterministic=False)
    np.testing.assert_allclose(model.policy.scale_action(deterministic), average, atol=1e-6)
    np.testing.assert_allclose(model.policy.scale_action(stochastic), actor, atol=1e-6)
    assert model.policy.drop_actor_average()
    assert not model.policy.drop_actor_average()  # nothing left to drop
    deterministic, _ = model.predict(observations, deterministic=True)
    np.testing.assert_allclose(model.policy.scale_action(deterministic), actor, atol=1e-6)


@pytest.mark.parametrize("algorithm", [ADC, AveragedActorTD3, SplitRateDDPG])
def test_a_saved_model_keeps_its_average_and_goes_on_averaging(tmp_path, algorithm):
    model = make(actor_average_tau=0.01, algorithm=algorithm).learn(200)
    model.save(tmp_path / "model.zip")
    model.save_replay_buffer(tmp_path / "buffer.pkl")
    loaded = algorithm.load(tmp_path / "model.zip", env=model.get_env())
    assert loaded.policy.actor_average_tau == 0.01
    average = vector(model.policy.actor_average)
    th.testing.assert_close(vector(loaded.policy.actor_average), average, rtol=0, atol=0)
    # The next actor update weighs the actor by the count of updates so far, not as a first update.
    loaded.load_replay_buffer(tmp_path / "buffer.pkl")
    loaded.set_logger(configure(None, []))
    n_updates = loaded._n_updates
    loaded.train(gradient_steps=2, batch_size=16)
    assert loaded._n_updates == n_updates + 2
    # ADC and TD3 (policy_delay 2) updated their actors once, DDPG twice.
    n_actor_updates, n_new = loaded._n_updates // loaded.policy_delay, 2 // loaded.policy_delay
    weight = actor_average_weight(0.01, n_actor_updates, n_new)
    assert weight < 1
    expected = (1 - weight) * average + weight * vector(loaded.actor)
    th.testing.assert_close(vector(loaded.policy.actor_average), expected)


@pytest.mark.parametrize("value", [-0.1, 1.0, 2, float("nan"), True, "0.1", None])
def test_invalid_values_name_the_option_and_the_accepted_values(value):
    with pytest.raises(ValueError, match=r"`actor_average_tau` must be a number >= 0 and < 1"):
        check_actor_average_tau(value)
    with pytest.raises(ValueError, match=r"`actor_average_tau`"):
        ADC("MlpPolicy", "Pendulum-v1", policy_kwargs={**NET, "actor_average_tau": value})


def test_the_policy_class_records_the_option_for_loading():
    model = make(actor_average_tau=0.2)
    assert isinstance(model.policy, ADCPolicy)
    assert model.policy._get_constructor_parameters()["actor_average_tau"] == 0.2


@pytest.mark.parametrize("algorithm", [ADC, AveragedActorTD3, SplitRateDDPG])
def test_training_mode_reaches_the_actor_and_critics_only(algorithm):
    """SB3's rule (the targets and the average stay in evaluation mode), with the walk skipped when nothing changes;
    a mode set on the actor or the critics alone is still corrected by the next call."""
    policy = make(actor_average_tau=0.05, algorithm=algorithm).policy
    learned = [policy.actor, policy.critic]
    fixed = [policy.actor_target, policy.critic_target, policy.actor_average]

    def modes(modules):
        return {submodule.training for module in modules for submodule in module.modules()}

    for mode in (True, True, False, False, True):
        policy.set_training_mode(mode)
        assert policy.training == mode
        assert modes(learned) == {mode}
        assert modes(fixed) == {False}
    policy.critic.set_training_mode(False)  # behind the policy's back
    policy.set_training_mode(True)
    assert modes(learned) == {True}
    policy.actor.set_training_mode(False)
    policy.set_training_mode(True)
    assert modes(learned) == {True}
