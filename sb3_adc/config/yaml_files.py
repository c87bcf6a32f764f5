"""
Bounded YAML: ``yaml.safe_load`` semantics, duplicate keys rejected, and limits on size, nesting, aliases and the values
the aliases expand to (a few hundred bytes can expand to billions), so that a small hostile file cannot exhaust memory.
"""

from __future__ import annotations

from collections.abc import Hashable
from typing import Any

import yaml

from sb3_adc.config.errors import HyperparamsError, short_repr

#: Largest YAML file read, in bytes (the shipped files are a few kB; PyYAML reads about 100 kB/s).
MAX_FILE_BYTES = 256 * 1024
#: Deepest nesting of collections (mappings and lists) in a YAML document (an entry needs about 4).
MAX_DEPTH = 32
#: Most aliases (``*name``, merge keys ``<<: *name`` included) in a YAML document.
MAX_ALIASES = 100
#: Most values (scalars and collections) in a YAML document once its aliases are expanded.
MAX_EXPANDED_VALUES = 100_000


class _YamlLimitExceeded(yaml.YAMLError):
    """A YAML document over one of the limits of this module (reported without the document's content)."""


class _HyperparamsYamlLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` rejecting duplicate keys, and documents over a limit while composing them."""

    _depth = _aliases = 0  # class defaults, shadowed per instance on first change

    def compose_node(self, parent: yaml.Node | None, index: Any) -> yaml.Node | None:
        at = f"line {self.peek_event().start_mark.line + 1}"
        self._aliases += self.check_event(yaml.AliasEvent)
        if self._aliases > MAX_ALIASES:
            raise _YamlLimitExceeded(f"more than {MAX_ALIASES} aliases ({at}); MAX_ALIASES={MAX_ALIASES}")
        # A collection is one level deeper (PyYAML composes them recursively).
        nested = self.check_event(yaml.SequenceStartEvent, yaml.MappingStartEvent)
        if nested and self._depth >= MAX_DEPTH:
            raise _YamlLimitExceeded(f"collections nested more than {MAX_DEPTH} levels deep ({at}); MAX_DEPTH={MAX_DEPTH}")
        self._depth += nested
        try:
            return super().compose_node(parent, index)
        finally:
            self._depth -= nested

    def get_single_node(self) -> yaml.Node | None:
        node = super().get_single_node()
        expanded = _expanded_size(node, {}) if node is not None and self._aliases else 0
        if expanded > MAX_EXPANDED_VALUES:
            limit = f"more than MAX_EXPANDED_VALUES={MAX_EXPANDED_VALUES}"
            raise _YamlLimitExceeded(f"its aliases expand to {expanded} values, {limit}")
        return node

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: set[Any] = set()
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue
            key = self.construct_object(key_node, deep=deep)
            if not isinstance(key, Hashable):
                continue  # SafeLoader reports unhashable keys
            if key in seen:
                raise yaml.constructor.ConstructorError(None, None, f"duplicate key {short_repr(key)}", key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


def _expanded_size(node: yaml.Node, sizes: dict[int, int]) -> int:
    """Number of values under ``node``, aliases expanded; each node's size is computed once (``sizes``)."""
    if id(node) not in sizes:
        children = node.value if isinstance(node, yaml.SequenceNode) else []
        if isinstance(node, yaml.MappingNode):
            children = [child for pair in node.value for child in pair]
        sizes[id(node)] = 1 + sum(_expanded_size(child, sizes) for child in children)
    return sizes[id(node)]


def load_yaml_bounded(text: str, source: str, key: str | None = None, what: str = "file") -> Any:
    """
    Read one YAML document within the limits of this module (the caller bounds the length).

    :param text: The document
    :param source: Where it comes from (a file path, ``command line``), for error messages
    :param key: The hyperparameter key it is the value of, if any, for error messages
    :param what: What the document is (``file``, ``value``), for error messages
    :raises HyperparamsError: if it is not valid YAML (or uses Python tags), or is over a limit
    """
    loader = _HyperparamsYamlLoader(text)
    try:
        return loader.get_single_data()
    except _YamlLimitExceeded as error:
        raise HyperparamsError(source, key, f"{what} is over a limit of sb3_adc.config.yaml_files: {error}") from None
    except yaml.YAMLError as error:
        raise HyperparamsError(source, key, f"{what} is not valid YAML (Python tags are not accepted): {error}") from None
    finally:
        loader.dispose()


def read_yaml_file(path: str) -> Any:
    """
    Read a YAML file of at most :data:`MAX_FILE_BYTES` bytes with :func:`load_yaml_bounded`.

    :param path: The file (it must exist)
    :raises HyperparamsError: if the file is not valid UTF-8 YAML or is over a limit
    """
    with open(path, "rb") as stream:
        data = stream.read(MAX_FILE_BYTES + 1)
    if len(data) > MAX_FILE_BYTES:
        raise HyperparamsError(path, None, f"file larger than {MAX_FILE_BYTES} bytes (MAX_FILE_BYTES of {__name__})")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise HyperparamsError(path, None, f"not a UTF-8 text file ({error.reason} at byte {error.start})") from None
    return load_yaml_bounded(text, path)
