"""
Reading RL-Zoo-format hyperparameter files safely: one YAML file per algorithm (``adc.yml``, ...) mapping environment
ids, and an optional ``default`` entry merged under each, to hyperparameters. Strings go through
:mod:`sb3_adc.config.expressions`: nothing is executed, or imported outside :mod:`sb3_adc.config.allowlists`.
"""

from __future__ import annotations

import difflib
import os
from collections.abc import Iterable, Mapping, Sequence
from importlib import resources
from typing import Any

import gymnasium as gym
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.utils import LinearSchedule

from sb3_adc.config.algorithms import get_algorithm
from sb3_adc.config.allowlists import CALLBACKS, ENV_WRAPPERS, EXPRESSION_NAMES, POLICIES, REPLAY_BUFFERS, AllowList
from sb3_adc.config.errors import HyperparamsError, short_repr
from sb3_adc.config.experiment_config import ExperimentConfig, NoiseSpec
from sb3_adc.config.expressions import parse_expression
from sb3_adc.config.schema import ADC_POLICY_KEYS, EPSILON_NOISE_KEYS, entry_keys
from sb3_adc.config.validators import Validator
from sb3_adc.config.yaml_files import MAX_FILE_BYTES, load_yaml_bounded, read_yaml_file

# The package of the shipped files, its folder of the paper's tables (`-conf paper/adc`), the entry merged under all.
HYPERPARAMS_PACKAGE, PAPER_FOLDER, DEFAULT_ENTRY = "sb3_adc.hyperparams", "paper", "default"
#: Keys whose string values (in ``policy_kwargs`` and similar mappings) name a class of the allow-list.
CLASS_VALUED_KWARGS = frozenset({"activation_fn", "features_extractor_class", "optimizer_class"})
#: Keywords of ``VecNormalize`` accepted in ``normalize``.
NORMALIZE_KEYS = frozenset({"norm_obs", "norm_reward", "clip_obs", "clip_reward", "gamma", "epsilon", "norm_obs_keys"})


def packaged_hyperparams_file(name: str) -> str:
    """
    Path of a shipped hyperparameter file (inside the installed package).

    :param name: The file's name without ``.yml``: an algorithm's name, or ``paper/{algo}``
    """
    return str(resources.files(HYPERPARAMS_PACKAGE).joinpath(*f"{name}.yml".split("/")))


def shipped_hyperparams_files() -> list[str]:
    """The names (without ``.yml``) of the hyperparameter files shipped with the package, ``paper/`` ones included."""
    folder = resources.files(HYPERPARAMS_PACKAGE)
    items = [("", item) for item in folder.iterdir()]
    if (paper := folder.joinpath(PAPER_FOLDER)).is_dir():
        items += [(f"{PAPER_FOLDER}/", item) for item in paper.iterdir()]
    return sorted(prefix + item.name[: -len(".yml")] for prefix, item in items if item.name.endswith(".yml"))


def find_hyperparams_file(conf_file: str) -> str:
    """
    The path of a hyperparameter file given as a path, or as the name of a shipped file (``adc``, ``paper/adc``).

    :param conf_file: A path, or the name of a shipped file
    :raises HyperparamsError: if it is neither
    """
    if os.path.isfile(conf_file):
        return conf_file
    shipped = shipped_hyperparams_files()
    if conf_file in shipped:
        return packaged_hyperparams_file(conf_file)
    raise HyperparamsError(conf_file, None, f"hyperparameter file not found (nor a shipped file: {', '.join(shipped)})")


def read_hyperparams_file(path: str) -> dict[str, Any]:
    """
    Read a hyperparameter file: a YAML mapping of entry names (environment ids, ``default``) to mappings.

    :param path: The file
    :raises HyperparamsError: if it is missing, not UTF-8 YAML within :mod:`sb3_adc.config.yaml_files`, or not that
    """
    if not os.path.isfile(path):
        raise HyperparamsError(path, None, "hyperparameter file not found")
    if (content := read_yaml_file(path)) is None:
        return {}
    if not isinstance(content, dict):
        raise HyperparamsError(path, None, f"expected a mapping of environment ids to entries, got {type(content).__name__}")
    for name, entry in content.items():
        if not isinstance(name, str):
            raise HyperparamsError(path, None, f"entry names must be environment ids (strings), got {short_repr(name)}")
        if not isinstance(entry, dict):
            problem = f"an entry must be a mapping of keys to values, got {short_repr(entry)}"
            raise HyperparamsError(f"{path} [{name}]", None, problem)
    return content


def select_entry(content: Mapping[str, Any], env_id: str, path: str) -> tuple[dict[str, Any], str]:
    """
    The entry of an environment, ``default`` merged under it, and its source (``path [env_id]`` or ``path [default]``).

    :param content: The file's content (see :func:`read_hyperparams_file`)
    :param env_id: The environment id
    :param path: The file, for error messages
    :raises HyperparamsError: if the file has neither an entry for ``env_id`` nor a ``default`` entry
    """
    default = dict(content.get(DEFAULT_ENTRY) or {})
    if env_id in content:
        return {**default, **content[env_id]}, f"{path} [{env_id}]"
    if DEFAULT_ENTRY in content:
        return default, f"{path} [{DEFAULT_ENTRY}]"
    entries = sorted(name for name in content if name != DEFAULT_ENTRY)
    problem = f"no entry for environment {env_id!r} and no {DEFAULT_ENTRY!r} entry; entries: {', '.join(entries)}"
    raise HyperparamsError(path, None, problem)


def parse_overrides(items: Sequence[str], source: str = "command line") -> dict[str, Any]:
    """
    Parse ``key:value`` overrides (``-params``), each value read as YAML: ``train_freq:[1,episode]``.

    :param items: The ``key:value`` strings
    :param source: Where they come from, for error messages
    :raises HyperparamsError: for an item without ``:`` or a value that is not valid YAML
    """
    overrides: dict[str, Any] = {}
    for item in items:
        key, separator, text = item.partition(":")
        if not separator or not key:
            raise HyperparamsError(source, None, "overrides must be written key:value", expression=item)
        if len(text) > MAX_FILE_BYTES:
            raise HyperparamsError(source, key, f"value longer than {MAX_FILE_BYTES} characters", expression=text[:80] + "...")
        overrides[key] = load_yaml_bounded(text, source, key, what="value")
    return overrides


def check_env_id(env_id: str) -> None:
    """
    Check that an environment id is registered with Gymnasium (``import sb3_adc`` registers ours).

    :param env_id: The id
    :raises HyperparamsError: for an unknown id, listing the closest registered ids and sb3-adc's own
    """
    if env_id in gym.registry:
        return
    from sb3_adc_envs.registration import ENV_SPECS

    close = difflib.get_close_matches(env_id, list(gym.registry), n=5, cutoff=0.5)
    known = f"closest registered ids: {', '.join(close) or 'none'}; sb3-adc's environments: {', '.join(sorted(ENV_SPECS))}"
    raise HyperparamsError("command line", "--env", f"unknown environment id {env_id!r}; {known}")


def load_hyperparams(
    algo: str,
    env_id: str,
    conf_file: str | None = None,
    overrides: Mapping[str, Any] | None = None,
    n_timesteps: int | None = None,
) -> ExperimentConfig:
    """
    Load and resolve the hyperparameters of ``algo`` on ``env_id``.

    :param algo: The algorithm's name (``adc``, ``ddpg``, ``td3``, ``sac``, ``dqn``, ``vanilla_ac``, ...)
    :param env_id: The environment id
    :param conf_file: A hyperparameter file, or a shipped one's name; ``None`` uses the shipped ``{algo}.yml``
    :param overrides: Values replacing those of the entry (see :func:`parse_overrides`)
    :param n_timesteps: Training budget replacing the entry's ``n_timesteps``
    :raises HyperparamsError: for any invalid file, entry, key or value
    """
    get_algorithm(algo)
    path = find_hyperparams_file(conf_file) if conf_file is not None else packaged_hyperparams_file(algo)
    entry, source = select_entry(read_hyperparams_file(path), env_id, path)
    if overrides:
        entry = apply_overrides(entry, overrides)
        source = f"{source} with command-line overrides of {', '.join(sorted(overrides))}"
    return resolve_entry(algo, env_id, entry, source, n_timesteps=n_timesteps)


def apply_overrides(entry: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """
    ``entry`` with the values of ``overrides``; one setting a ``noise_type`` other than ``epsilon-normal`` drops the
    entry's epsilon keys (the RL Zoo's ``-params noise_type:...`` replaces the noise), not those the overrides give.

    :param entry: A hyperparameter entry
    :param overrides: The values replacing the entry's
    """
    other_noise = overrides.get("noise_type", "epsilon-normal") != "epsilon-normal"
    dropped = set(EPSILON_NOISE_KEYS) - set(overrides) if other_noise else set()
    return {key: value for key, value in {**entry, **overrides}.items() if key not in dropped}


def _reject_unknown(given: Iterable[Any], accepted: Iterable[str], source: str, what: str, prefix: str = "") -> None:
    """Raise for the first name of ``given`` not ``accepted``, listing those and the closest ("did you mean")."""
    accepted = sorted(accepted)
    if unknown := sorted(set(given) - set(accepted)):
        close = difflib.get_close_matches(str(unknown[0]), accepted, n=3, cutoff=0.6)
        suggestion = f"; did you mean {' or '.join(f'`{match}`' for match in close)}?" if close else ""
        raise HyperparamsError(source, f"{prefix}{unknown[0]}", f"unknown {what}: {', '.join(accepted)}{suggestion}")


def resolve_entry(
    algo: str, env_id: str, entry: Mapping[str, Any], source: str, n_timesteps: int | None = None
) -> ExperimentConfig:
    """
    Validate one entry and resolve it into an :class:`~sb3_adc.config.experiment_config.ExperimentConfig`.

    :param algo: The algorithm's name
    :param env_id: The environment id
    :param entry: The entry (``default`` already merged), as read from YAML
    :param source: Where the entry comes from, for error messages
    :param n_timesteps: Training budget replacing the entry's ``n_timesteps``
    :raises HyperparamsError: for an unknown key, an invalid value or expression, or a missing required key
    """
    algorithm_class = get_algorithm(algo, source, "algo")
    keys, policy_kwargs_keys, constructor_keys = entry_keys(algorithm_class)
    _reject_unknown(entry, keys, source, f"key for {algo} ({algorithm_class.__name__}); accepted keys")
    values = {key: keys[key](value, source, key) for key, value in entry.items()}
    if n_timesteps is not None:
        values["n_timesteps"] = keys["n_timesteps"](n_timesteps, "command line", "n_timesteps")
    if missing := [key for key in ("n_timesteps", "policy") if key not in values]:
        raise HyperparamsError(source, missing[0], "required key missing")
    n_envs = int(values.get("n_envs", 1))
    noise = _resolve_noise(values, source, n_envs)
    model_kwargs: dict[str, Any] = {"policy": _resolve_policy(values["policy"], algorithm_class, source)}
    policy_kwargs = _resolve_policy_kwargs(values, source, policy_kwargs_keys)
    model_kwargs.update({"policy_kwargs": policy_kwargs} if policy_kwargs else {})
    model_kwargs.update({name: _model_value(name, values[name], source) for name in constructor_keys if name in values})
    return ExperimentConfig(
        algo=algo,
        env_id=env_id,
        source=source,
        algorithm_class=algorithm_class,
        n_timesteps=int(values["n_timesteps"]),
        n_envs=n_envs,
        model_kwargs=model_kwargs,
        env_kwargs=dict(values.get("env_kwargs") or {}),
        env_wrappers=_resolve_classes(values.get("env_wrapper"), ENV_WRAPPERS, source, "env_wrapper"),
        normalize=_resolve_normalize(values.get("normalize", False), values.get("gamma"), source),
        frame_stack=values.get("frame_stack"),
        callbacks=_resolve_classes(values.get("callback"), CALLBACKS, source, "callback"),
        noise=noise,
        saved=dict(sorted(values.items())),
    )


def _resolve_noise(values: dict[str, Any], source: str, n_envs: int) -> NoiseSpec | None:
    noise_type = values.get("noise_type")
    epsilon_keys = sorted(set(EPSILON_NOISE_KEYS) & set(values))
    if noise_type != "epsilon-normal" and epsilon_keys:
        raise HyperparamsError(source, epsilon_keys[0], "only accepted with `noise_type: epsilon-normal`")
    if noise_type is None:
        if "noise_std" in values:
            raise HyperparamsError(source, "noise_std", "needs `noise_type` (normal, ornstein-uhlenbeck or epsilon-normal)")
        return None
    if "noise_std" not in values:
        raise HyperparamsError(source, "noise_std", f"required with `noise_type: {noise_type}`")
    if noise_type == "epsilon-normal":
        # Default: epsilon reaches its final value half-way through training (counted per environment).
        defaults = {"epsilon_decay_steps": values["n_timesteps"] // n_envs // 2, "epsilon_initial": 1.0, "epsilon_final": 0.0}
        values.update({key: values.get(key, default) for key, default in defaults.items()})
    return NoiseSpec(noise_type, values["noise_std"], **{key: values[key] for key in EPSILON_NOISE_KEYS if key in values})


def _resolve_policy(name: str, algorithm_class: type[BaseAlgorithm], source: str) -> str | object:
    aliases = sorted(getattr(algorithm_class, "policy_aliases", {}))
    if name in aliases:
        return name
    if name in POLICIES:
        return POLICIES.resolve(name, source, "policy")
    accepted = ", ".join(aliases + POLICIES.names())
    raise HyperparamsError(source, "policy", f"unknown policy {name!r} for {algorithm_class.__name__}; accepted: {accepted}")


def _kwargs_from(value: dict[str, Any] | str | None, source: str, key: str) -> dict[str, Any]:
    """A mapping, or an expression string that must evaluate to a mapping; class-valued keys resolved."""
    parsed = parse_expression(value, source, key) if isinstance(value, str) else dict(value or {})
    if not isinstance(parsed, dict):
        raise HyperparamsError(source, key, "must be a mapping such as dict(net_arch=[64, 64])", expression=str(value))
    resolve = EXPRESSION_NAMES.resolve
    return {
        name: resolve(item, source, f"{key}.{name}") if name in CLASS_VALUED_KWARGS and isinstance(item, str) else item
        for name, item in parsed.items()
    }


def _resolve_policy_kwargs(values: dict[str, Any], source: str, checked: dict[str, Validator]) -> dict[str, Any]:
    policy_kwargs = _kwargs_from(values.get("policy_kwargs"), source, "policy_kwargs")
    for name in sorted(checked.keys() & policy_kwargs.keys()):
        policy_kwargs[name] = checked[name](policy_kwargs[name], source, f"policy_kwargs.{name}")
    for name in [name for name in ADC_POLICY_KEYS if name in values]:
        if name in policy_kwargs and policy_kwargs[name] != values[name]:
            conflict = f"conflicts with policy_kwargs {name}={short_repr(policy_kwargs[name])}; set it in one place only"
            raise HyperparamsError(source, name, conflict, expression=short_repr(values[name]))
        policy_kwargs[name] = values[name]
    return policy_kwargs


def _model_value(name: str, value: Any, source: str) -> Any:
    if name in ("learning_rate", "critic_learning_rate") and isinstance(value, str):
        return LinearSchedule(float(value.partition("_")[2]), 0.0, 1.0)
    if name == "train_freq" and isinstance(value, list):
        return tuple(value)
    if name == "replay_buffer_class" and value is not None:
        return REPLAY_BUFFERS.resolve(value, source, name)
    if name == "replay_buffer_kwargs" and value is not None:
        return _kwargs_from(value, source, name)
    return value


def _resolve_classes(value: Any, allowlist: AllowList, source: str, key: str) -> list[tuple[Any, dict[str, Any]]]:
    if value is None or isinstance(value, list):
        return [resolved for element in value or [] for resolved in _resolve_classes(element, allowlist, source, key)]
    ((name, kwargs),) = value.items() if isinstance(value, dict) else [(value, {})]
    return [(allowlist.resolve(name, source, key), dict(kwargs))]


def _resolve_normalize(value: bool | dict[str, Any] | str, gamma: float | None, source: str) -> dict[str, Any] | None:
    if value is False:
        return None
    kwargs = {} if value is True else _kwargs_from(value, source, "normalize")
    _reject_unknown(kwargs, NORMALIZE_KEYS, source, "VecNormalize keyword; accepted", prefix="normalize.")
    if gamma is not None:  # as the RL Zoo: the reward normalization discounts with the algorithm's gamma
        kwargs.setdefault("gamma", gamma)
    return kwargs
