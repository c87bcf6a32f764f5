"""
A restricted parser for the Python-like strings of RL-Zoo hyperparameter files.

The RL Zoo ``eval``s strings such as ``"dict(net_arch=[400, 300], activation_fn=nn.ReLU)"``. This module
reads the same strings without executing anything: it walks the syntax tree and accepts only

- literals: numbers (with an optional sign), strings, ``True``, ``False``, ``None``;
- lists, tuples and dicts of accepted expressions;
- ``dict(key=value, ...)`` calls with keyword arguments only;
- names and dotted names of an allow-list (:data:`~sb3_adc.config.allowlists.EXPRESSION_NAMES`:
  torch activation functions and optimizers, SB3 features extractors).

Everything else (other calls, attribute access outside the allow-list, dunder names, subscripts, operators,
lambdas, comprehensions, f-strings, imports, ...) is rejected with a
:class:`~sb3_adc.config.errors.HyperparamsError` naming the source, the key and the offending expression.
"""

from __future__ import annotations

import ast
from typing import Any

from sb3_adc.config.allowlists import EXPRESSION_NAMES, AllowList
from sb3_adc.config.errors import HyperparamsError, short_repr

#: Longest expression accepted (characters).
MAX_EXPRESSION_LENGTH = 10_000

_NODE_DESCRIPTIONS: dict[type[ast.AST], str] = {
    ast.Lambda: "lambda functions",
    ast.ListComp: "comprehensions",
    ast.SetComp: "comprehensions",
    ast.DictComp: "comprehensions",
    ast.GeneratorExp: "generator expressions",
    ast.JoinedStr: "f-strings",
    ast.FormattedValue: "f-strings",
    ast.Subscript: "subscripts (indexing)",
    ast.BinOp: "operators",
    ast.BoolOp: "operators",
    ast.Compare: "comparisons",
    ast.IfExp: "conditional expressions",
    ast.NamedExpr: "assignment expressions",
    ast.Starred: "unpacking",
    ast.Await: "await",
    ast.Yield: "yield",
    ast.YieldFrom: "yield",
    ast.Set: "sets",
    ast.Slice: "slices",
}


def _dotted_name(node: ast.expr) -> str | None:
    """``a.b.c`` for a chain of attribute accesses on a name, else ``None``."""
    parts: list[str] = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if not isinstance(node, ast.Name):
        return None
    parts.append(node.id)
    return ".".join(reversed(parts))


class _RestrictedEvaluator:
    def __init__(self, text: str, source: str, key: str, names: AllowList):
        self.text = text
        self.source = source
        self.key = key
        self.names = names

    def reject(self, node: ast.AST, problem: str) -> HyperparamsError:
        segment = ast.get_source_segment(self.text, node) or self.text
        context = "" if segment == self.text else f" in {short_repr(self.text)}"
        return HyperparamsError(self.source, self.key, f"{problem}{context}", expression=segment)

    def evaluate(self, node: ast.AST) -> Any:
        if isinstance(node, ast.Constant):
            if isinstance(node.value, (bool, int, float, str)) or node.value is None:
                return node.value
            raise self.reject(node, f"constants of type {type(node.value).__name__} are not allowed")
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            operand = node.operand
            number = operand.value if isinstance(operand, ast.Constant) else None
            if isinstance(number, (int, float)) and not isinstance(number, bool):
                return -number if isinstance(node.op, ast.USub) else number
            raise self.reject(node, "a sign is only allowed before a number")
        if isinstance(node, ast.List):
            return [self.evaluate(element) for element in node.elts]
        if isinstance(node, ast.Tuple):
            return tuple(self.evaluate(element) for element in node.elts)
        if isinstance(node, ast.Dict):
            result: dict[Any, Any] = {}
            for key_node, value_node in zip(node.keys, node.values, strict=True):
                if key_node is None:
                    raise self.reject(value_node, "`**` unpacking is not allowed")
                key = self.evaluate(key_node)
                if not isinstance(key, (str, int, float, bool)):
                    raise self.reject(key_node, "dict keys must be strings or numbers")
                result[key] = self.evaluate(value_node)
            return result
        if isinstance(node, ast.Call):
            return self.evaluate_call(node)
        if isinstance(node, (ast.Name, ast.Attribute)):
            return self.evaluate_name(node)
        description = _NODE_DESCRIPTIONS.get(type(node), f"{type(node).__name__} expressions")
        raise self.reject(node, f"{description} are not allowed")

    def evaluate_call(self, node: ast.Call) -> dict[str, Any]:
        if not (isinstance(node.func, ast.Name) and node.func.id == "dict"):
            raise self.reject(node, "function calls are not allowed (only `dict(key=value, ...)`)")
        if node.args:
            raise self.reject(node, "`dict(...)` takes keyword arguments only")
        result: dict[str, Any] = {}
        for keyword in node.keywords:
            if keyword.arg is None:
                raise self.reject(node, "`**` unpacking is not allowed")
            result[keyword.arg] = self.evaluate(keyword.value)
        return result

    def evaluate_name(self, node: ast.Name | ast.Attribute) -> object:
        name = _dotted_name(node)
        if name is None:
            raise self.reject(node, "attribute access is only allowed on allow-listed names")
        if any(part.startswith("__") or part.endswith("__") for part in name.split(".")):
            raise self.reject(node, f"dunder names are not allowed ({name!r})")
        if name not in self.names:
            raise self.reject(node, f"name {name!r} is not allowed; accepted names: {', '.join(self.names.names())}")
        return self.names.resolve(name, self.source, self.key)


def parse_expression(text: str, source: str, key: str, names: AllowList = EXPRESSION_NAMES) -> Any:
    """
    Read a Python-like expression without executing it.

    ``parse_expression("dict(net_arch=[64, 64], activation_fn=nn.Tanh)", "adc.yml", "policy_kwargs")``
    returns ``{"net_arch": [64, 64], "activation_fn": torch.nn.Tanh}``.

    :param text: The expression
    :param source: Where it was read (file and entry), for error messages
    :param key: The hyperparameter key it is the value of, for error messages
    :param names: The names the expression may use
    :return: The value of the expression
    :raises HyperparamsError: if the text is not an expression, or uses anything outside the accepted subset
    """
    if len(text) > MAX_EXPRESSION_LENGTH:
        raise HyperparamsError(
            source, key, f"expression longer than {MAX_EXPRESSION_LENGTH} characters", expression=text[:80] + "..."
        )
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as error:
        raise HyperparamsError(
            source,
            key,
            f"not a valid expression ({error.msg}); accepted: literals, lists, tuples, dicts, `dict(key=value, ...)` "
            "and allow-listed names such as nn.ReLU",
            expression=text,
        ) from None
    except (RecursionError, MemoryError):
        # Python's parser gives up on operators or attribute chains nested some thousand levels deep.
        raise HyperparamsError(source, key, "expression nested too deeply", expression=text) from None
    return _RestrictedEvaluator(text.strip(), source, key, names).evaluate(tree.body)
