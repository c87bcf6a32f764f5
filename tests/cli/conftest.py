"""Tiny hyperparameter files (small networks, 50-step episodes) for end-to-end tests of the command line."""

import textwrap

import pytest

from sb3_adc.cli import main

# 50-step episodes keep evaluations cheap; the networks have a handful of units.
TINY_CONFIGS = {
    "adc": """
        default: &defaults
          n_timesteps: 300
          policy: MlpPolicy
          learning_starts: 100
          batch_size: 16
          buffer_size: 1000
          gamma: 0.9
          noise_type: epsilon-normal
          noise_std: 0.1
          n_intervals: 10
          policy_kwargs: "dict(net_arch=[8], value_net_arch=[4])"
          env_kwargs: {max_episode_steps: 50}
        Pendulum-v1: {}
        sb3_adc/NoisyPendulum-v1: {}
        """,
    "ddpg": """
        default:
          n_timesteps: 300
          policy: MlpPolicy
          learning_starts: 100
          batch_size: 16
          buffer_size: 1000
          critic_learning_rate: !!float 2e-3
          noise_type: normal
          noise_std: 0.1
          policy_kwargs: "dict(net_arch=[8])"
          env_kwargs: {max_episode_steps: 50}
        """,
    "dqn": """
        default:
          n_timesteps: 300
          policy: sb3_adc.baselines.DuelingDQNPolicy
          env_wrapper:
            - sb3_adc_envs.wrappers.DiscretizedActions: {n_actions: 25}
          learning_starts: 100
          batch_size: 16
          buffer_size: 1000
          target_update_interval: 50
          policy_kwargs: "dict(net_arch=[8], value_net_arch=[4], advantage_net_arch=[4])"
          env_kwargs: {max_episode_steps: 50}
        """,
    "sac": """
        default:
          n_timesteps: 300
          policy: MlpPolicy
          learning_starts: 100
          batch_size: 16
          buffer_size: 1000
          policy_kwargs: "dict(net_arch=[8])"
          env_kwargs: {max_episode_steps: 50}
        """,
    "vanilla_ac": """
        default:
          n_timesteps: 300
          policy: MlpPolicy
          learning_rate: !!float 1e-3
          critic_learning_rate: !!float 2e-3
          noise_type: epsilon-normal
          noise_std: 0.1
          policy_kwargs: "dict(net_arch=[8])"
          env_kwargs: {max_episode_steps: 50}
        """,
}


@pytest.fixture(scope="session")
def tiny_conf(tmp_path_factory):
    """Folder with a tiny ``{algo}.yml`` per algorithm."""
    folder = tmp_path_factory.mktemp("tiny_conf")
    for algo, text in TINY_CONFIGS.items():
        (folder / f"{algo}.yml").write_text(textwrap.dedent(text))
    return folder


@pytest.fixture
def cli(capsys):
    """Run ``sb3-adc`` in this process; returns (exit status, stdout, stderr)."""

    def run(*args):
        status = main([str(arg) for arg in args])
        captured = capsys.readouterr()
        return status, captured.out, captured.err

    return run


@pytest.fixture
def train_args(tiny_conf):
    """Arguments of a tiny ``sb3-adc train`` run: 300 steps, an evaluation every 100."""

    def build(algo, log_folder, *extra, seed=0, env="Pendulum-v1"):
        return [
            "train",
            "--algo",
            algo,
            "--env",
            env,
            "-conf",
            tiny_conf / f"{algo}.yml",
            "-f",
            log_folder,
            "--seed",
            seed,
            "--eval-freq",
            100,
            "--eval-episodes",
            1,
            "--final-eval-episodes",
            2,
            *extra,
        ]

    return build
