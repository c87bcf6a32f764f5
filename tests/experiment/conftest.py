"""
Tiny hyperparameter files (small networks, 50-step episodes), and the settings of tiny runs and tiny tuning studies of
the experiment engine.
"""

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from sb3_adc.experiment import TrainSettings
from sb3_adc.experiment.tuning import TuneSettings

TINY_ADC = """\
default:
  n_timesteps: 300
  policy: MlpPolicy
  learning_starts: 50
  batch_size: 16
  buffer_size: 1000
  gamma: 0.9
  noise_type: normal
  noise_std: 0.1
  n_intervals: 4
  policy_kwargs: "dict(net_arch=[8], value_net_arch=[4])"
  env_kwargs: {max_episode_steps: 50}
"""
TINY_CONFIGS = {
    "adc": TINY_ADC,
    # With VecNormalize: a checkpoint holds all four kinds of file.
    "adc-normalized": TINY_ADC + "  normalize: true\n",
    "ddpg": """\
default:
  n_timesteps: 100
  policy: MlpPolicy
  learning_starts: 50
  batch_size: 16
  buffer_size: 200
  gamma: 0.9
  policy_kwargs: "dict(net_arch=[4])"
  env_kwargs: {max_episode_steps: 50}
""",
}


@pytest.fixture(scope="session")
def tiny_conf(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Folder with a tiny ``{name}.yml`` per entry of :data:`TINY_CONFIGS`."""
    folder = tmp_path_factory.mktemp("tiny_conf")
    for name, text in TINY_CONFIGS.items():
        (folder / f"{name}.yml").write_text(text)
    return folder


@pytest.fixture(scope="session")
def tiny_settings(tiny_conf: Path) -> Callable[..., TrainSettings]:
    """
    Settings of a tiny run on Pendulum-v1 logging under ``folder/logs``, seed 3: an evaluation (of one episode) and
    a checkpoint every 100 timesteps, the last 3 kept, a final evaluation of one episode, on the CPU.
    ``make(folder, conf="adc", **changes)``: ``conf`` names a file of :data:`TINY_CONFIGS` or is a path.
    """

    def make(folder: Path, conf: str | Path = "adc", **changes: Any) -> TrainSettings:
        conf_file = str(tiny_conf / f"{conf}.yml" if isinstance(conf, str) else conf)
        values: dict[str, Any] = dict(algo="adc", env_id="Pendulum-v1", seed=3, conf_file=conf_file, device="cpu")
        values.update(eval_freq=100, eval_episodes=1, save_freq=100, keep_checkpoints=3, final_eval_episodes=1)
        return TrainSettings(**{**values, "log_folder": str(folder / "logs"), "progress_bar": False, **changes})

    return make


@pytest.fixture
def tiny_study(tmp_path: Path) -> Callable[..., TuneSettings]:
    """
    Settings of a tuning study of DDPG on Pendulum-v1 in ``tmp_path``, with tiny networks and budgets: one trial of
    two seeds of 200 steps, two evaluations each, no pruner, on the CPU. ``make(**changes)`` changes any of them.
    """

    def make(**changes: Any) -> TuneSettings:
        values: dict[str, Any] = dict(
            algo="ddpg",
            env_id="Pendulum-v1",
            n_trials=1,
            n_timesteps=200,
            seeds=(0, 1),
            n_evaluations=2,
            eval_episodes=1,
            final_eval_episodes=1,
            pruner="none",
            log_folder=str(tmp_path),
            overrides={"learning_starts": 100, "policy_kwargs": {"net_arch": [4]}, "batch_size": 8},
            device="cpu",
        )
        values.update(changes)
        return TuneSettings(**values)

    return make
