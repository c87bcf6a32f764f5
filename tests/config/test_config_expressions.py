"""The restricted expression parser: what it accepts, and that it rejects (without running) anything else."""

import os

import pytest
import torch as th
from stable_baselines3.common.sb2_compat.rmsprop_tf_like import RMSpropTFLike
from stable_baselines3.common.torch_layers import NatureCNN

from sb3_adc.config import AllowList, HyperparamsError, parse_expression


def parse(text):
    return parse_expression(text, "hyperparams/adc.yml [Pendulum-v1]", "policy_kwargs")


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("dict(net_arch=[400, 300], activation_fn=nn.ReLU)", {"net_arch": [400, 300], "activation_fn": th.nn.ReLU}),
        (
            "dict(net_arch=dict(pi=[30], qf=[30]), n_intervals=100, value_net_arch=[20])",
            {"net_arch": {"pi": [30], "qf": [30]}, "n_intervals": 100, "value_net_arch": [20]},
        ),
        (
            "{'log_std_init': -2.5, 'train_freq': (1, 'episode'), 'x': None, 'ortho_init': False}",
            {"log_std_init": -2.5, "train_freq": (1, "episode"), "x": None, "ortho_init": False},
        ),
        (
            "dict(activation_fn=th.nn.Tanh, optimizer_class=th.optim.AdamW)",
            {"activation_fn": th.nn.Tanh, "optimizer_class": th.optim.AdamW},
        ),
        ("dict(activation_fn=torch.nn.ELU)", {"activation_fn": th.nn.ELU}),
        (
            "dict(features_extractor_class=NatureCNN, optimizer_class=RMSpropTFLike)",
            {"features_extractor_class": NatureCNN, "optimizer_class": RMSpropTFLike},
        ),
        ("dict()", {}),
        ("  [1, +2, -3.5e-3]  ", [1, 2, -3.5e-3]),
    ],
)
def test_accepts_literals_dicts_and_allowlisted_names(text, expected):
    result = parse(text)
    assert result == expected


@pytest.mark.parametrize(
    ("text", "offending", "problem"),
    [
        ("dict(a=__import__('os').system('echo pwned'))", "__import__('os').system('echo pwned')", "function calls"),
        ("os.system('ls')", "os.system('ls')", "function calls"),
        ("open('/etc/passwd').read()", "open('/etc/passwd').read()", "function calls"),
        ("eval('1 + 1')", "eval('1 + 1')", "function calls"),
        ("nn.ReLU()", "nn.ReLU()", "function calls"),
        ("getattr(nn, 'ReLU')", "getattr(nn, 'ReLU')", "function calls"),
        ("import os", "import os", "not a valid expression"),
        ("dict(a=nn.ReLU.__class__)", "nn.ReLU.__class__", "dunder names"),
        ("__builtins__", "__builtins__", "dunder names"),
        ("dict(a=nn.Module)", "nn.Module", "not allowed"),
        ("dict(a=os.environ)", "os.environ", "not allowed"),
        ("dict(a=nn.ReLU.mro)", "nn.ReLU.mro", "not allowed"),
        ("dict(a=[].copy)", "[].copy", "attribute access"),
        ("().__class__.__bases__[0]", "().__class__.__bases__[0]", "subscripts"),
        ("dict(f=lambda x: x)", "lambda x: x", "lambda"),
        ("[x for x in range(3)]", "[x for x in range(3)]", "comprehensions"),
        ("{k: 1 for k in 'ab'}", "{k: 1 for k in 'ab'}", "comprehensions"),
        ("dict(a=f'{nn}')", "f'{nn}'", "f-strings"),
        ("dict(**{'a': 1})", "dict(**{'a': 1})", "unpacking"),
        ("{**{'a': 1}}", "{'a': 1}", "unpacking"),
        ("dict([('a', 1)])", "dict([('a', 1)])", "keyword arguments only"),
        ("dict(a=9 ** 9 ** 9)", "9 ** 9 ** 9", "operators"),
        ("dict(a=1 if True else 2)", "1 if True else 2", "conditional"),
        ("{1, 2}", "{1, 2}", "sets"),
        ("dict(a=b'raw')", "b'raw'", "bytes"),
        ("dict(a=-nn.ReLU)", "-nn.ReLU", "sign"),
        ("dict(a=(x := 1))", "x := 1", "assignment"),
        ("dict(net_arch=[64, 64]", "dict(net_arch=[64, 64]", "not a valid expression"),
    ],
)
def test_rejects_code_naming_file_key_and_expression(text, offending, problem):
    with pytest.raises(HyperparamsError) as info:
        parse(text)
    message = str(info.value)
    assert "hyperparams/adc.yml [Pendulum-v1]" in message
    assert "`policy_kwargs`" in message
    assert problem in message
    assert info.value.expression == offending
    assert offending in message


def test_rejected_code_is_never_run(tmp_path):
    marker = tmp_path / "marker"
    for text in (
        f"open({str(marker)!r}, 'w')",
        f"__import__('pathlib').Path({str(marker)!r}).touch()",
        f"dict(a=[open({str(marker)!r}, 'w')])",
    ):
        with pytest.raises(HyperparamsError):
            parse(text)
    assert not os.path.exists(marker)


def test_names_come_from_the_given_allowlist_only():
    names = AllowList("name", {"my.Activation": "torch.nn:GELU"})
    assert parse_expression("dict(a=my.Activation)", "f.yml", "k", names) == {"a": th.nn.GELU}
    with pytest.raises(HyperparamsError, match=r"accepted names: my\.Activation"):
        parse_expression("dict(a=nn.ReLU)", "f.yml", "k", names)


def test_overlong_expression_is_rejected():
    with pytest.raises(HyperparamsError, match="longer than"):
        parse("[" + "1, " * 5000 + "1]")
