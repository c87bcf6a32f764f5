"""
A restricted parser for the Python-like strings of RL-Zoo hyperparameter files (which the RL Zoo runs with ``eval``):
literals (signed numbers, strings, booleans, ``None``), lists, tuples and dicts of them, ``dict(key=value, ...)`` and
allow-listed names (:data:`~sb3_adc.config.allowlists.EXPRESSION_NAMES`); anything else is a HyperparamsError.
"""

from __future__ import annotations

import ast
from typing import Any

from sb3_adc.config.allowlists import EXPRESSION_NAMES, AllowList
from sb3_adc.config.errors import HyperparamsError, short_repr

#: Longest expression accepted (characters).
MAX_EXPRESSION_LENGTH = 10_000

_NODE_DESCRIPTIONS: dict[type[ast.AST], str] = {
    **dict.fromkeys((ast.ListComp, ast.SetComp, ast.DictComp), "comprehensions"),
    **dict.fromkeys((ast.JoinedStr, ast.FormattedValue), "f-strings"),
    **dict.fromkeys((ast.BinOp, ast.BoolOp), "operators"),
    **dict.fromkeys((ast.Yield, ast.YieldFrom), "yield"),
    ast.Lambda: "lambda functions",
    ast.GeneratorExp: "generator expressions",
    ast.Subscript: "subscripts (indexing)",
    ast.Compare: "comparisons",
    ast.IfExp: "conditional expressions",
    ast.NamedExpr: "assignment expressions",
    ast.Starred: "unpacking",
    ast.Await: "await",
    ast.Set: "sets",
    ast.Slice: "slices",
}


def parse_expression(text: str, source: str, key: str, names: AllowList = EXPRESSION_NAMES) -> Any:
    """
    Read a Python-like expression without executing it: ``"dict(net_arch=[64])"`` -> ``{"net_arch": [64]}``.

    :param text: The expression
    :param source: Where it was read (file and entry), for error messages
    :param key: The hyperparameter key it is the value of, for error messages
    :param names: The names the expression may use
    :return: The value of the expression
    :raises HyperparamsError: if the text is not an expression, or uses anything outside the accepted subset
    """
    if len(text) > MAX_EXPRESSION_LENGTH:
        too_long = f"expression longer than {MAX_EXPRESSION_LENGTH} characters"
        raise HyperparamsError(source, key, too_long, expression=text[:80] + "...")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as error:
        accepted = "literals, lists, tuples, dicts, `dict(key=value, ...)` and allow-listed names such as nn.ReLU"
        problem = f"not a valid expression ({error.msg}); accepted: {accepted}"
        raise HyperparamsError(source, key, problem, expression=text) from None
    except (RecursionError, MemoryError):
        # Python's parser gives up on operators or attribute chains nested some thousand levels deep.
        raise HyperparamsError(source, key, "expression nested too deeply", expression=text) from None
    text = text.strip()

    def reject(node: ast.AST, problem: str) -> HyperparamsError:
        segment = ast.get_source_segment(text, node) or text
        context = "" if segment == text else f" in {short_repr(text)}"
        return HyperparamsError(source, key, f"{problem}{context}", expression=segment)

    def evaluate(node: ast.AST) -> Any:
        if isinstance(node, ast.Constant):
            if isinstance(node.value, (bool, int, float, str)) or node.value is None:
                return node.value
            raise reject(node, f"constants of type {type(node.value).__name__} are not allowed")
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            number = node.operand.value if isinstance(node.operand, ast.Constant) else None
            if isinstance(number, (int, float)) and not isinstance(number, bool):
                return -number if isinstance(node.op, ast.USub) else number
            raise reject(node, "a sign is only allowed before a number")
        if isinstance(node, (ast.List, ast.Tuple)):
            return (list if isinstance(node, ast.List) else tuple)(evaluate(element) for element in node.elts)
        if isinstance(node, ast.Dict):
            result: dict[Any, Any] = {}
            for key_node, value_node in zip(node.keys, node.values, strict=True):
                if key_node is None:
                    raise reject(value_node, "`**` unpacking is not allowed")
                name = evaluate(key_node)
                if not isinstance(name, (str, int, float, bool)):
                    raise reject(key_node, "dict keys must be strings or numbers")
                result[name] = evaluate(value_node)
            return result
        if isinstance(node, ast.Call):
            if not (isinstance(node.func, ast.Name) and node.func.id == "dict"):
                raise reject(node, "function calls are not allowed (only `dict(key=value, ...)`)")
            if node.args:
                raise reject(node, "`dict(...)` takes keyword arguments only")
            arguments: dict[str, Any] = {}
            for keyword in node.keywords:
                if keyword.arg is None:
                    raise reject(node, "`**` unpacking is not allowed")
                arguments[keyword.arg] = evaluate(keyword.value)
            return arguments
        if isinstance(node, (ast.Name, ast.Attribute)):
            base: ast.expr = node
            attributes: list[str] = []
            while isinstance(base, ast.Attribute):  # a loop, not ast.unparse: chains may be thousands long
                attributes.insert(0, base.attr)
                base = base.value
            if not isinstance(base, ast.Name):
                raise reject(node, "attribute access is only allowed on allow-listed names")
            name = ".".join([base.id, *attributes])
            if any(part.startswith("__") or part.endswith("__") for part in name.split(".")):
                raise reject(node, f"dunder names are not allowed ({name!r})")
            if name not in names:
                raise reject(node, f"name {name!r} is not allowed; accepted names: {', '.join(names.names())}")
            return names.resolve(name, source, key)
        raise reject(node, f"{_NODE_DESCRIPTIONS.get(type(node), f'{type(node).__name__} expressions')} are not allowed")

    return evaluate(tree.body)
