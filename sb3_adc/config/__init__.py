"""
RL-Zoo-format hyperparameter files, read safely: ``load_hyperparams("adc", "Pendulum-v1")`` reads the shipped
``adc.yml`` into an :class:`ExperimentConfig`; nothing in a file is ever executed.
"""

from sb3_adc.config.algorithms import ALGORITHMS, get_algorithm
from sb3_adc.config.allowlists import CALLBACKS, ENV_WRAPPERS, EXPRESSION_NAMES, POLICIES, REPLAY_BUFFERS, AllowList
from sb3_adc.config.errors import HyperparamsError
from sb3_adc.config.experiment_config import ExperimentConfig, NoiseSpec
from sb3_adc.config.expressions import parse_expression
from sb3_adc.config.loader import (
    check_env_id,
    load_hyperparams,
    packaged_hyperparams_file,
    parse_overrides,
    read_hyperparams_file,
    resolve_entry,
    select_entry,
)

__all__ = ["ALGORITHMS", "CALLBACKS", "ENV_WRAPPERS", "EXPRESSION_NAMES", "POLICIES", "REPLAY_BUFFERS", "AllowList"]
__all__ += ["ExperimentConfig", "HyperparamsError", "NoiseSpec", "check_env_id", "get_algorithm", "load_hyperparams"]
__all__ += ["packaged_hyperparams_file", "parse_expression", "parse_overrides", "read_hyperparams_file", "resolve_entry"]
__all__ += ["select_entry"]
