"""
Replacements for the parts of the RL Zoo that execute configuration text.

The Zoo ``eval``s ``-params`` / ``--env-kwargs`` values (``StoreDict``), reads a run's ``config.yml`` and
``args.yml`` with ``yaml.UnsafeLoader`` and ``eval``s string ``normalize`` values, and imports any module an
``env_wrapper`` names. The bridge swaps these for the versions below, which go through
:mod:`sb3_adc.config` (bounded safe YAML loading, the restricted expression parser, the allow-lists).
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Sequence
from types import SimpleNamespace
from typing import Any

import yaml

from sb3_adc.config import HyperparamsError, resolve_entry
from sb3_adc.config.loader import MAX_FILE_BYTES, load_yaml_bounded, parse_overrides, read_yaml_file


class SafeStoreDict(argparse.Action):
    """
    ``argparse`` action storing ``key:value`` items as a dict, each value read as YAML (never ``eval``'d):
    the Zoo's ``-params learning_rate:0.001 policy_kwargs:"dict(net_arch=[64])"`` keeps working, the
    ``policy_kwargs`` string going through the restricted parser when the hyperparameters are resolved.
    """

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: str | Sequence[Any] | None,
        option_string: str | None = None,
    ) -> None:
        items = [values] if isinstance(values, str) else [str(value) for value in values or []]
        setattr(namespace, self.dest, parse_overrides(items, source=f"command line {option_string}"))


def _safe_load(stream: Any, Loader: Any = None) -> Any:
    """
    ``yaml.load`` with ``yaml.safe_load`` semantics whatever loader is asked for, within the limits of
    :mod:`sb3_adc.config.loader` (size, depth, aliases): an alias bomb is a ``HyperparamsError``.
    """
    source = str(getattr(stream, "name", "YAML document"))
    text = stream if isinstance(stream, (str, bytes)) else stream.read(MAX_FILE_BYTES + 1)
    if len(text) > MAX_FILE_BYTES:
        raise HyperparamsError(source, None, f"larger than {MAX_FILE_BYTES} bytes (MAX_FILE_BYTES of sb3_adc.config.loader)")
    if isinstance(text, bytes):
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError as error:
            raise HyperparamsError(source, None, f"not UTF-8 text ({error.reason} at byte {error.start})") from None
    return load_yaml_bounded(text, source)


#: Stands for the ``yaml`` module inside ``rl_zoo3.enjoy``: its ``yaml.load(..., Loader=yaml.UnsafeLoader)``
#: of ``args.yml`` becomes a safe, bounded load.
SAFE_YAML = SimpleNamespace(load=_safe_load, safe_load=_safe_load, UnsafeLoader=None, SafeLoader=yaml.SafeLoader)


def safe_get_saved_hyperparams(
    stats_path: str, norm_reward: bool = False, test_mode: bool = False
) -> tuple[dict[str, Any], str | None]:
    """
    Replacement of ``rl_zoo3.utils.get_saved_hyperparams`` for runs trained through the bridge: the run's
    ``config.yml`` and ``args.yml`` are read with safe YAML and resolved by :mod:`sb3_adc.config`, and the
    environment wrappers come back as classes (the Zoo then imports nothing by name).

    :param stats_path: The run's ``{run_dir}/{env_name}`` folder
    :param norm_reward: Whether to normalize rewards (with ``normalize``)
    :param test_mode: Unused (the Zoo's signature)
    :return: The hyperparameters the Zoo's ``enjoy`` needs, and ``stats_path`` (``None`` if it does not exist)
    """
    if not os.path.isdir(stats_path):
        return {}, None
    config_path, args_path = os.path.join(stats_path, "config.yml"), os.path.join(stats_path, "args.yml")
    if not (os.path.isfile(config_path) and os.path.isfile(args_path)):
        raise FileNotFoundError(f"{stats_path} lacks config.yml or args.yml: was this run trained with python -m sb3_adc.zoo?")
    args, entry = read_yaml_file(args_path), read_yaml_file(config_path)
    if not isinstance(args, dict) or not {"algo", "env"} <= set(args):
        raise HyperparamsError(args_path, None, "expected the run's arguments (a mapping with `algo` and `env`)")
    config = resolve_entry(args["algo"], args["env"], entry, config_path)
    hyperparams: dict[str, Any] = {"normalize": config.normalize is not None, "env_kwargs": dict(config.env_kwargs)}
    if config.normalize is not None:
        hyperparams["normalize_kwargs"] = {**config.normalize, "norm_reward": norm_reward}
    if config.env_wrappers:
        hyperparams["env_wrapper"] = [{wrapper: kwargs} for wrapper, kwargs in config.env_wrappers]
    if config.frame_stack is not None:
        hyperparams["frame_stack"] = config.frame_stack
    return hyperparams, stats_path
