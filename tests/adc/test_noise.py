"""EpsilonGaussianNoise: the epsilon-gated Gaussian exploration of ADC's Algorithm 1 (line 5)."""

import itertools

import numpy as np
import pytest
from stable_baselines3.common.noise import VectorizedActionNoise

from sb3_adc import EpsilonGaussianNoise


def noisy_fraction(noise, n_calls):
    return np.mean([np.any(noise() != 0) for _ in range(n_calls)])


def test_epsilon_decays_linearly_then_stays_final():
    noise = EpsilonGaussianNoise(np.zeros(1), np.ones(1), decay_steps=100, initial_epsilon=1.0, final_epsilon=0.2)
    seen = []
    for _ in range(150):
        seen.append(noise.epsilon)
        noise()
    assert seen[0] == pytest.approx(1.0)
    assert seen[50] == pytest.approx(0.6)
    assert seen[100] == pytest.approx(0.2)
    assert seen[149] == pytest.approx(0.2)
    assert all(a >= b for a, b in itertools.pairwise(seen))


def test_fraction_of_noisy_actions_follows_epsilon():
    np.random.seed(0)
    n = 4000
    noise = EpsilonGaussianNoise(np.zeros(2), np.ones(2), decay_steps=2 * n)
    # Over the first n calls epsilon falls linearly from 1 to 0.5: expected noisy fraction 0.75.
    first = noisy_fraction(noise, n)
    # Over the next n calls it falls from 0.5 to 0: expected 0.25.
    second = noisy_fraction(noise, n)
    # Binomial standard deviation is below 0.007 here; allow 4 of them.
    assert first == pytest.approx(0.75, abs=0.03)
    assert second == pytest.approx(0.25, abs=0.03)
    assert noisy_fraction(noise, 500) == 0.0


def test_noise_is_gaussian_when_applied():
    np.random.seed(1)
    noise = EpsilonGaussianNoise(np.array([0.5]), np.array([0.2]), decay_steps=0, initial_epsilon=1.0, final_epsilon=1.0)
    samples = np.array([noise() for _ in range(5000)])
    assert samples.shape == (5000, 1)
    assert samples.dtype == np.float32
    assert samples.mean() == pytest.approx(0.5, abs=0.02)
    assert samples.std() == pytest.approx(0.2, abs=0.02)


def test_one_bernoulli_draw_for_the_whole_action_vector():
    np.random.seed(2)
    noise = EpsilonGaussianNoise(np.zeros(4), np.ones(4), decay_steps=1000, initial_epsilon=0.5, final_epsilon=0.5)
    draws = np.array([noise() for _ in range(500)])
    zero_rows = np.all(draws == 0, axis=1)
    nonzero_rows = np.all(draws != 0, axis=1)
    assert np.all(zero_rows | nonzero_rows)
    assert 0.4 < zero_rows.mean() < 0.6


def test_reset_keeps_the_decay_and_reset_schedule_restarts_it():
    noise = EpsilonGaussianNoise(np.zeros(1), np.ones(1), decay_steps=10)
    for _ in range(5):
        noise()
    noise.reset()  # what SB3 calls at the end of every episode
    assert noise.n_calls == 5
    assert noise.epsilon == pytest.approx(0.5)
    noise.reset_schedule()
    assert noise.epsilon == pytest.approx(1.0)


def test_works_inside_vectorized_action_noise():
    np.random.seed(3)
    base = EpsilonGaussianNoise(np.zeros(1), np.ones(1), decay_steps=10)
    vectorized = VectorizedActionNoise(base, n_envs=3)
    out = vectorized()
    assert out.shape == (3, 1)
    for _ in range(20):
        vectorized()
    vectorized.reset([0])
    # Each environment has its own copy, decayed over its own calls.
    assert all(noise.n_calls == 21 for noise in vectorized.noises)
    assert all(noise.epsilon == 0.0 for noise in vectorized.noises)
    assert np.all(vectorized() == 0)


def test_same_global_seed_gives_same_noise():
    def draw():
        np.random.seed(7)
        noise = EpsilonGaussianNoise(np.zeros(1), np.ones(1), decay_steps=50)
        return np.array([noise() for _ in range(50)])

    np.testing.assert_array_equal(draw(), draw())


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(decay_steps=-1), "decay_steps"),
        (dict(decay_steps=1.5), "decay_steps"),
        (dict(decay_steps=10, initial_epsilon=1.5), "initial_epsilon"),
        (dict(decay_steps=10, final_epsilon=-0.1), "final_epsilon"),
        (dict(decay_steps=10, sigma=np.array([-1.0])), "sigma"),
        (dict(decay_steps=10, sigma=np.array([np.inf])), "sigma"),
        (dict(decay_steps=10, mean=np.array([np.nan])), "mean"),
        (dict(decay_steps=10, mean=np.zeros(2), sigma=np.ones(3)), "same shape"),
    ],
)
def test_invalid_arguments_are_rejected(kwargs, match):
    arguments = dict(mean=np.zeros(1), sigma=np.ones(1))
    arguments.update(kwargs)
    with pytest.raises(ValueError, match=match):
        EpsilonGaussianNoise(**arguments)
