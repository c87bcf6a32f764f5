"""
A pytest plugin that runs Stable-Baselines3's own TD3 tests against one of sb3-adc's TD3-family classes (used by
``test_sb3_td3_suite.py``).

Loaded with ``-p td3_as_adc`` before SB3's test modules are imported, it rebinds ``stable_baselines3.TD3`` to the
class ``SB3_ADC_SUITE_CLASS`` names (:data:`CLASSES`: ``adc``, the default, is :class:`sb3_adc.ADC`;
``averaged_td3`` is :class:`~sb3_adc.baselines.AveragedActorTD3` with the averaged actor on, the ``td3`` every
comparison runs), so that ``from stable_baselines3 import TD3`` in those modules, their parametrizations
included, get it. It then keeps only the tests that exercise TD3 (the class): those parametrized with it, and the
unparametrized ones whose code names ``TD3``; every other algorithm's tests are deselected, as are those of
:data:`NOT_APPLICABLE` (each with the reason it cannot apply) and, unless ``SB3_ADC_SB3_SUITE=all``, the slow
ones of :data:`SLOW`.
"""

from __future__ import annotations

import os
from typing import Any

import pytest
import stable_baselines3
import stable_baselines3.td3
from stable_baselines3.common.base_class import BaseAlgorithm

from sb3_adc import ADC
from sb3_adc.baselines import AveragedActorTD3


class AveragingTD3(AveragedActorTD3):
    """
    :class:`~sb3_adc.baselines.AveragedActorTD3` whose ``MlpPolicy`` deploys the averaged actor unless told
    otherwise (``actor_average_tau`` 0.01: SB3's tests train for a few hundred steps), so that SB3's tests
    exercise the average: predictions, saving and loading, training and evaluation modes.
    """

    def __init__(self, policy: Any, env: Any, *args: Any, policy_kwargs: dict[str, Any] | None = None, **kwargs: Any):
        if policy == "MlpPolicy":
            policy_kwargs = {"actor_average_tau": 0.01, **(policy_kwargs or {})}
        super().__init__(policy, env, *args, policy_kwargs=policy_kwargs, **kwargs)


#: The classes the suite runs against, by ``SB3_ADC_SUITE_CLASS``.
CLASSES: dict[str, type[BaseAlgorithm]] = {"adc": ADC, "averaged_td3": AveragingTD3}
UNDER_TEST = CLASSES[os.environ.get("SB3_ADC_SUITE_CLASS", "adc")]
stable_baselines3.TD3 = UNDER_TEST  # type: ignore[misc]
stable_baselines3.td3.TD3 = UNDER_TEST  # type: ignore[misc]

#: SB3 TD3 tests that do not apply to the class under test (node id as pytest prints it, with ``TD3`` read as the
#: class's name): the reason.
NOT_APPLICABLE: dict[str, str] = (
    {
        "tests/test_tensorboard.py::test_tensorboard[td3]": (
            'expects the TensorBoard run to be named after TD3 ("TD3_1"); ADC names its runs "ADC_1", as every SB3 '
            "algorithm names them after itself"
        ),
    }
    if UNDER_TEST is ADC
    else {
        "tests/test_save_load.py::test_save_load_policy[False-MlpPolicy-AveragingTD3]": (
            "asserts that the policy predicts what `policy.actor` predicts; with the average on, the policy deploys the "
            "averaged actor and `policy.actor` is the actor being learned, by design (the test's save-and-load checks "
            "before that assertion pass)"
        ),
        "tests/test_dict_env.py::test_consistency[AveragingTD3]": (
            "compares a MultiInputPolicy model with an MlpPolicy one on the same observations; only MlpPolicy has the "
            "averaged variant, which this class turns on, so the two deploy different policies"
        ),
        "tests/test_save_load.py::test_save_load_large_model": (
            "loads with `policy_kwargs` that leave out the `actor_average_tau` this class adds by default, which SB3 "
            "refuses as kwargs that differ from the stored ones"
        ),
    }
)

#: Tests that pass but take most of the run time (image observations, a model of over 2 GB, 180 gradient steps):
#: deselected unless ``SB3_ADC_SB3_SUITE=all``, to keep the default run near a minute. Node id prefix: reason.
SLOW: dict[str, str] = {
    "tests/test_save_load.py::test_save_load_large_model": "saves and loads a model of over 2 GB",
    "tests/test_save_load.py::test_save_load_env_cnn": "trains a CNN policy on images",
    "tests/test_save_load.py::test_save_load_policy[False-CnnPolicy": "trains a CNN policy on images",
    "tests/test_save_load.py::test_save_load_policy[True-CnnPolicy": "trains a CNN policy on images",
    "tests/test_save_load.py::test_warn_buffer": "180 gradient steps at batch size 256, for a warning of SB3's buffer",
}
RUN_ALL = os.environ.get("SB3_ADC_SB3_SUITE") == "all"


def _exercises_td3(item: pytest.Item) -> bool:
    callspec = getattr(item, "callspec", None)
    parameters: list[Any] = list(callspec.params.values()) if callspec is not None else []
    algorithms = [value for value in parameters if isinstance(value, type) and issubclass(value, BaseAlgorithm)]
    if algorithms:
        return UNDER_TEST in algorithms
    if any(isinstance(value, str) and value.lower() == "td3" for value in parameters):
        return True  # a test parametrized by algorithm name (test_tensorboard.py)
    code = getattr(getattr(item, "function", None), "__code__", None)
    return code is not None and "TD3" in code.co_names


def _is_slow(item: pytest.Item) -> bool:
    return not RUN_ALL and any(item.nodeid.startswith(prefix) for prefix in SLOW)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    kept = [item for item in items if _exercises_td3(item) and item.nodeid not in NOT_APPLICABLE and not _is_slow(item)]
    deselected = [item for item in items if item not in kept]
    if deselected:
        config.hook.pytest_deselected(items=deselected)
    items[:] = kept


def pytest_report_header(config: pytest.Config) -> list[str]:
    lines = [
        f"stable_baselines3.TD3 is {UNDER_TEST.__module__}.{UNDER_TEST.__qualname__}; only the tests that exercise it run"
    ]
    lines += [f"not applicable: {node}: {reason}" for node, reason in NOT_APPLICABLE.items()]
    if not RUN_ALL:
        lines += [f"slow, run with SB3_ADC_SB3_SUITE=all: {node}: {reason}" for node, reason in SLOW.items()]
    return lines
