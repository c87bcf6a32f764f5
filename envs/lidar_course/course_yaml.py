"""Reading a course file's YAML within bounds: a linear pre-scan, then PyYAML with limits checked while composing.

A course is a few hundred bytes, but PyYAML's cost grows faster than the length for some documents: flow
collections nested many levels deep (``[[[[...]]]]``) make its scanner track a possible key per level, so
200 kB of brackets take minutes before anything reports an error, and aliases (``*name``) expand a few hundred
bytes into gigabytes. :func:`load_course_yaml` therefore

1. counts the nesting of flow brackets in one pass over the text (:func:`flow_depth_exceeds`), before PyYAML
   sees it, and
2. composes the document with a loader that refuses aliases, collections nested more than
   :data:`MAX_YAML_DEPTH` levels deep (block ones included) and documents of more than :data:`MAX_YAML_VALUES`
   values, before any Python object is built.

It reads numbers as YAML 1.2 does: ``1e3`` and ``-1e300`` are floats (PyYAML's YAML 1.1 reads an exponent without
a dot as a string).

``sb3_adc.config.loader`` bounds the hyperparameter files the same way, but it imports Stable-Baselines3, and
``sb3_adc_envs`` must import without it (tests/envs/test_env_conventions.py), so the course files have this small
module of their own. The caller bounds the text's length.
"""

from __future__ import annotations

import re
from typing import Any

import yaml

#: Deepest nesting of collections (mappings and lists) in a course file: a course needs 4 (``walls``: the list of
#: polylines, a polyline, a point, inside the top-level mapping).
MAX_YAML_DEPTH = 16
#: Most values (scalars, lists and mappings) in a course file: a course at every count limit of
#: :mod:`~sb3_adc_envs.lidar_course.course` has about 19,000 (2,000 centre-line and 2,000 wall points of 3 values
#: each, 500 obstacles of about 12).
MAX_YAML_VALUES = 50_000

# Characters after which a quote opens a quoted scalar in the pre-scan (and at the start of a line).
_QUOTE_OPENERS = frozenset(":-[{,?")
# A plain YAML 1.1 float needs a dot; YAML 1.2 (and JSON) also accept an exponent without one.
_EXPONENT_FLOAT = re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$")


class CourseYamlError(yaml.YAMLError):
    """A course file over a limit of this module, or with aliases (the message names the limit and the line)."""


def flow_depth_exceeds(text: str, limit: int = MAX_YAML_DEPTH) -> int | None:
    """
    Whether flow collections (``[...]``, ``{...}``) nest more than ``limit`` levels deep, in one pass over the text.

    Brackets inside quoted scalars and comments are skipped. The scan is conservative: a plain scalar full of
    unbalanced opening brackets (``text: [[[[``) counts as nesting, which only means that such a file is refused
    with a clear message, as nothing a course needs looks like that.

    :param text: The document
    :param limit: The deepest nesting accepted
    :return: The line (from 1) where the nesting goes deeper than ``limit``, or ``None`` if it never does
    """
    depth = 0
    line = 1
    quote = ""
    previous = "\n"  # the last character outside a quoted scalar that is not a space
    i, length = 0, len(text)
    while i < length:
        char = text[i]
        if char == "\n":
            line += 1
        if quote:
            if char == "\\" and quote == '"':
                i += 1  # an escaped character
            elif char == quote:
                if quote == "'" and text[i + 1 : i + 2] == "'":
                    i += 1  # '' is a quote inside a single-quoted scalar
                else:
                    quote = ""
                    previous = char
        elif char == "#" and (i == 0 or text[i - 1] in " \t\n"):
            end = text.find("\n", i)
            i = length if end < 0 else end
            continue
        elif char in "'\"" and (previous in _QUOTE_OPENERS or previous == "\n"):
            quote = char
        elif char in "[{":
            depth += 1
            if depth > limit:
                return line
        elif char in "]}":
            depth = max(depth - 1, 0)
        if not quote and char not in " \t\r":
            previous = char
        i += 1
    return None


class _CourseYamlLoader(yaml.SafeLoader):
    """
    PyYAML's safe loader, reading floats as YAML 1.2 does, refusing aliases, collections nested more than
    :data:`MAX_YAML_DEPTH` levels deep and documents of more than :data:`MAX_YAML_VALUES` values while composing.
    """

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0
        self._values = 0

    def compose_node(self, parent: yaml.Node | None, index: Any) -> yaml.Node | None:
        mark = self.peek_event().start_mark
        where = f" (line {mark.line + 1})" if mark is not None else ""
        if self.check_event(yaml.AliasEvent):
            raise CourseYamlError(f"YAML aliases (*name) are not allowed in course files{where}; write the values out.")
        self._values += 1
        if self._values > MAX_YAML_VALUES:
            raise CourseYamlError(
                f"more than MAX_YAML_VALUES = {MAX_YAML_VALUES:,} values{where}; a course file needs far fewer."
            )
        if not self.check_event(yaml.SequenceStartEvent, yaml.MappingStartEvent):
            return super().compose_node(parent, index)
        if self._depth >= MAX_YAML_DEPTH:
            raise CourseYamlError(
                f"lists or mappings nested more than MAX_YAML_DEPTH = {MAX_YAML_DEPTH} levels deep{where}; a course needs 4."
            )
        self._depth += 1
        try:
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


# PyYAML implements YAML 1.1, where a float needs a dot and a signed exponent (``1.0e+3``); YAML 1.2 and JSON
# accept ``1e3``. The resolver below adds the exponent forms without a dot; every other scalar resolves as before.
_CourseYamlLoader.add_implicit_resolver("tag:yaml.org,2002:float", _EXPONENT_FLOAT, list("-+0123456789"))


def load_course_yaml(text: str) -> Any:
    """
    Read one YAML document of a course file within the limits of this module.

    :param text: The document (the caller bounds its length)
    :return: Its content
    :raises CourseYamlError: if it is over a limit or has aliases (a :class:`yaml.YAMLError`)
    :raises yaml.YAMLError: if it is not valid YAML
    """
    line = flow_depth_exceeds(text)
    if line is not None:
        raise CourseYamlError(
            f"lists or mappings nested more than MAX_YAML_DEPTH = {MAX_YAML_DEPTH} levels deep (line {line}); "
            "a course needs 4."
        )
    loader = _CourseYamlLoader(text)
    try:
        return loader.get_single_data()
    finally:
        loader.dispose()
