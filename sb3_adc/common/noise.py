"""Action noise for the exploration of the Actor-Dueling-Critic method."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike, DTypeLike
from stable_baselines3.common.noise import ActionNoise, VectorizedActionNoise


class EpsilonGaussianNoise(ActionNoise):
    """
    Gaussian action noise applied with a probability epsilon that decays over training.

    Actor-Dueling-Critic paper, Algorithm 1, line 5: "with probability epsilon select action
    ``a_t = mu(s_t) + N_t``, otherwise select ``a_t = mu(s_t)``", with epsilon decreasing from 1 to 0.
    Each call draws one Bernoulli(epsilon) for the whole action vector: with probability epsilon it returns
    ``N(mean, sigma)`` noise, otherwise zeros. Epsilon decays linearly from ``initial_epsilon`` to
    ``final_epsilon`` over ``decay_steps`` calls and then stays at ``final_epsilon``.

    SB3 calls the noise once per environment step with the scaled action in ``[-1, 1]``, so ``sigma`` is in
    that scale. Inside :class:`~stable_baselines3.common.noise.VectorizedActionNoise` each environment gets
    its own copy, so with ``n_envs`` environments epsilon reaches its final value after ``decay_steps``
    steps of each environment (``decay_steps * n_envs`` timesteps in total).

    ``reset()`` is what SB3 calls at the end of every episode: it leaves epsilon alone, since the decay
    runs over the whole of training (Algorithm 1 decays it across episodes). :meth:`reset_schedule` starts
    the decay again. The draws come from NumPy's global generator, as SB3's own noises, so the model's
    ``seed`` makes them reproducible.

    :param mean: Mean of the Gaussian noise
    :param sigma: Standard deviation of the Gaussian noise (>= 0)
    :param decay_steps: Number of calls over which epsilon decays (>= 0; 0 means ``final_epsilon`` at once)
    :param initial_epsilon: Epsilon at the first call, in ``[0, 1]`` (1 in the paper)
    :param final_epsilon: Epsilon after ``decay_steps`` calls, in ``[0, 1]`` (0 in the paper)
    :param dtype: Type of the output noise
    """

    def __init__(
        self,
        mean: ArrayLike,
        sigma: ArrayLike,
        decay_steps: int,
        initial_epsilon: float = 1.0,
        final_epsilon: float = 0.0,
        dtype: DTypeLike = np.float32,
    ) -> None:
        super().__init__()
        self._mu = np.asarray(mean, dtype=np.float64)
        self._sigma = np.asarray(sigma, dtype=np.float64)
        if self._mu.shape != self._sigma.shape and self._mu.size != 1 and self._sigma.size != 1:
            raise ValueError(f"`mean` and `sigma` must have the same shape, got {self._mu.shape} and {self._sigma.shape}.")
        if not np.all(np.isfinite(self._mu)):
            raise ValueError(f"`mean` must be finite, got {mean!r}.")
        if not (np.all(np.isfinite(self._sigma)) and np.all(self._sigma >= 0)):
            raise ValueError(f"`sigma` must be finite and >= 0, got {sigma!r}.")
        if isinstance(decay_steps, bool) or not isinstance(decay_steps, (int, np.integer)) or decay_steps < 0:
            raise ValueError(f"`decay_steps` must be an integer >= 0 (a number of calls), got {decay_steps!r}.")
        for name, value in (("initial_epsilon", initial_epsilon), ("final_epsilon", final_epsilon)):
            if not 0.0 <= float(value) <= 1.0:
                raise ValueError(f"`{name}` must be a probability in [0, 1], got {value!r}.")
        self.decay_steps = int(decay_steps)
        self.initial_epsilon = float(initial_epsilon)
        self.final_epsilon = float(final_epsilon)
        self._dtype = dtype
        self._zeros = np.zeros(np.broadcast_shapes(self._mu.shape, self._sigma.shape), dtype=dtype)
        #: Number of calls so far (drives the decay).
        self.n_calls = 0

    @property
    def shape(self) -> tuple[int, ...]:
        """Shape of the noise a call returns (that of ``mean`` and ``sigma``)."""
        return self._zeros.shape

    @property
    def epsilon(self) -> float:
        """Probability that the next call returns Gaussian noise."""
        if self.n_calls >= self.decay_steps:
            return self.final_epsilon
        fraction = self.n_calls / self.decay_steps
        return self.initial_epsilon + fraction * (self.final_epsilon - self.initial_epsilon)

    def __call__(self) -> np.ndarray:
        epsilon = self.epsilon
        self.n_calls += 1
        # NumPy's global generator, as SB3's noises: seeded by the model's `seed`.
        if np.random.random() < epsilon:  # noqa: NPY002
            return np.asarray(np.random.normal(self._mu, self._sigma), dtype=self._dtype)  # noqa: NPY002
        return self._zeros.copy()

    def reset(self) -> None:
        """End of an episode: nothing to reset, epsilon keeps decaying across episodes."""

    def reset_schedule(self) -> None:
        """Start the epsilon decay again from ``initial_epsilon``."""
        self.n_calls = 0

    def __repr__(self) -> str:
        return (
            f"EpsilonGaussianNoise(mean={self._mu}, sigma={self._sigma}, decay_steps={self.decay_steps}, "
            f"initial_epsilon={self.initial_epsilon}, final_epsilon={self.final_epsilon}, n_calls={self.n_calls})"
        )


def _noise_shape(action_noise: ActionNoise) -> tuple[int, ...] | None:
    """The shape of the noise ``action_noise`` draws, where it says (``mean``/``sigma``), else ``None``."""
    if isinstance(action_noise, EpsilonGaussianNoise):
        return action_noise.shape
    mu, sigma = getattr(action_noise, "_mu", None), getattr(action_noise, "_sigma", None)  # SB3's Gaussian noises
    if isinstance(mu, np.ndarray) and isinstance(sigma, np.ndarray):
        try:
            return tuple(np.broadcast_shapes(mu.shape, sigma.shape))
        except ValueError:
            return None
    return None


def check_action_noise(action_noise: ActionNoise | None, action_space: spaces.Space) -> None:
    """
    Raise an error unless ``action_noise`` draws one value per dimension of ``action_space``.

    SB3 adds the noise to the action with NumPy broadcasting: noise of one value (``mean=np.zeros(1)``) on a
    3-dimensional action would silently add the same draw to every dimension, and noise of another length fails
    only at the first step. Noises that do not expose ``mean`` and ``sigma`` are not checked.

    :param action_noise: The algorithm's ``action_noise`` (``None``: no noise), possibly a
        :class:`~stable_baselines3.common.noise.VectorizedActionNoise`
    :param action_space: The environment's action space
    :raises ValueError: naming ``mean``/``sigma``, their shape and the action space's dimension
    """
    if action_noise is None or not isinstance(action_space, spaces.Box):
        return
    noises = action_noise.noises if isinstance(action_noise, VectorizedActionNoise) else [action_noise]
    action_shape = tuple(action_space.shape)
    n_actions = int(np.prod(action_shape))
    for noise in noises:
        shape = _noise_shape(noise)
        if shape is None or shape == action_shape or (n_actions == 1 and int(np.prod(shape)) == 1):
            continue
        raise ValueError(
            f"`action_noise` ({type(noise).__name__}): `mean` and `sigma` have shape {shape}, but the action space "
            f"has shape {action_shape} ({n_actions} action dimensions); give one value per dimension, e.g. "
            f"mean=np.zeros({n_actions}), sigma=np.full({n_actions}, 0.1) (a single value would add the same noise "
            "to every dimension)."
        )
