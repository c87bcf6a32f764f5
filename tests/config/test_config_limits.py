"""Hostile hyperparameter input fails fast, with a short error naming the file and the limit."""

import itertools
import time
import tracemalloc

import pytest

from sb3_adc.config import HyperparamsError, load_hyperparams, parse_overrides, read_hyperparams_file, yaml_files
from sb3_adc.config.errors import MAX_SHOWN_CHARACTERS, short_repr
from sb3_adc.config.expressions import parse_expression

ENTRY = "Pendulum-v1:\n  n_timesteps: 1000\n  policy: MlpPolicy\n"


def alias_bomb(levels=9, width=9):
    """The "billion laughs" in YAML: each level lists the previous one `width` times (width**levels strings)."""
    lines = ["a: &a [" + ", ".join(['"lol"'] * width) + "]"]
    names = "abcdefghijklmnopqrstuvwxyz"[:levels]
    for previous, name in itertools.pairwise(names):
        lines.append(f"{name}: &{name} [" + ", ".join([f"*{previous}"] * width) + "]")
    return "\n".join(lines) + "\n"


def check_short_error(error, path):
    message = str(error)
    assert str(path) in message
    assert len(message) < 500
    assert "lol" not in message  # nothing of the content is shown


@pytest.mark.parametrize(
    "text",
    [
        alias_bomb(),
        # The bomb as an entry: the entry-is-not-a-mapping error used to show its (expanded) repr.
        alias_bomb() + "Pendulum-v1: *i\n",
        # Fewer aliases, still millions of values once expanded.
        alias_bomb(levels=7, width=9),
    ],
)
def test_alias_bombs_fail_fast_with_a_short_error(tmp_path, text):
    assert len(text.encode()) < 500
    path = tmp_path / "bomb.yml"
    path.write_text(text)
    tracemalloc.start()
    started = time.perf_counter()
    with pytest.raises(HyperparamsError, match=r"over a limit .*aliases expand to \d+ values.*MAX_EXPANDED_VALUES") as error:
        read_hyperparams_file(str(path))
    elapsed = time.perf_counter() - started
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert elapsed < 2.0
    assert peak < 20 * 2**20
    check_short_error(error.value, path)


def test_alias_count_is_bounded(tmp_path):
    aliases = "".join(f"  k{i}: *x\n" for i in range(yaml_files.MAX_ALIASES + 1))
    path = tmp_path / "aliases.yml"
    path.write_text("x: &x 1\nPendulum-v1:\n" + aliases)
    with pytest.raises(HyperparamsError, match=rf"more than {yaml_files.MAX_ALIASES} aliases") as error:
        read_hyperparams_file(str(path))
    check_short_error(error.value, path)


def test_plain_aliases_and_merge_keys_still_work(tmp_path):
    path = tmp_path / "anchors.yml"
    path.write_text(
        "default: &base\n  n_timesteps: 1000\n  policy: MlpPolicy\n"
        "Pendulum-v1:\n  <<: *base\n  gamma: 0.9\n  policy_kwargs: &arch {net_arch: [8]}\n"
        "MountainCarContinuous-v0:\n  <<: *base\n  policy_kwargs: *arch\n"
    )
    config = load_hyperparams("adc", "MountainCarContinuous-v0", conf_file=str(path))
    assert config.model_kwargs["policy_kwargs"]["net_arch"] == [8]
    assert read_hyperparams_file(str(path))["Pendulum-v1"]["gamma"] == 0.9


@pytest.mark.parametrize("nesting", ["[" * 700 + "]" * 700, "{a: " * 700 + "1" + "}" * 700])
def test_deep_nesting_is_an_error_not_a_recursion_error(tmp_path, nesting):
    path = tmp_path / "deep.yml"
    path.write_text(f"Pendulum-v1:\n  policy_kwargs: {nesting}\n")
    with pytest.raises(HyperparamsError, match=rf"nested more than {yaml_files.MAX_DEPTH} levels deep") as error:
        read_hyperparams_file(str(path))
    check_short_error(error.value, path)


def test_nesting_up_to_the_limit_is_read(tmp_path):
    path = tmp_path / "deep.yml"
    depth = yaml_files.MAX_DEPTH - 2  # the document's mapping and the entry's are levels too
    path.write_text(f"Pendulum-v1:\n  x: {'[' * depth}1{']' * depth}\n")
    value = read_hyperparams_file(str(path))["Pendulum-v1"]["x"]
    for _ in range(depth):
        (value,) = value
    assert value == 1


def test_large_files_are_refused_before_parsing(tmp_path):
    path = tmp_path / "large.yml"
    padding = "# " + "x" * 98 + "\n"
    path.write_text(ENTRY + padding * (yaml_files.MAX_FILE_BYTES // len(padding) + 1))
    started = time.perf_counter()
    with pytest.raises(HyperparamsError, match=rf"larger than {yaml_files.MAX_FILE_BYTES} bytes") as error:
        read_hyperparams_file(str(path))
    assert time.perf_counter() - started < 1.0
    check_short_error(error.value, path)
    # Just under the limit is read.
    path.write_text(ENTRY + padding * ((yaml_files.MAX_FILE_BYTES - len(ENTRY)) // len(padding)))
    assert read_hyperparams_file(str(path))["Pendulum-v1"]["n_timesteps"] == 1000


def test_files_that_are_not_utf8_are_refused(tmp_path):
    path = tmp_path / "binary.yml"
    path.write_bytes(ENTRY.encode() + b"\xff\xfe\x00")
    with pytest.raises(HyperparamsError, match=r"binary\.yml: not a UTF-8 text file"):
        read_hyperparams_file(str(path))


def test_command_line_values_have_the_same_limits():
    with pytest.raises(HyperparamsError, match=r"command line: `policy_kwargs`: value is over a limit .*nested"):
        parse_overrides(["policy_kwargs:" + "[" * 100 + "]" * 100])
    with pytest.raises(HyperparamsError, match=r"`gamma`: value is not valid YAML"):
        parse_overrides(["gamma:[0.9"])


@pytest.mark.parametrize("text", ["-" * 5000 + "1", "nn." * 3000 + "ReLU"])
def test_deeply_nested_expressions_are_an_error_not_a_recursion_error(text):
    with pytest.raises(HyperparamsError, match="nested too deeply") as error:
        parse_expression(text, "my.yml [Pendulum-v1]", "policy_kwargs")
    assert len(str(error.value)) < 500


def test_short_repr_does_not_expand_shared_collections():
    level = ["lol"] * 9
    for _ in range(9):
        level = [level] * 9  # 9**10 strings, if expanded
    started = time.perf_counter()
    shown = short_repr(level)
    assert time.perf_counter() - started < 1.0  # microseconds when bounded; expanding 9**10 strings would take hours
    assert len(shown) <= MAX_SHOWN_CHARACTERS + 3
    assert short_repr("x" * 10_000).startswith("'xxx")
    assert len(short_repr("x" * 10_000)) <= MAX_SHOWN_CHARACTERS + 3


def test_an_option_can_be_validated_by_the_class_that_owns_it():
    from sb3_adc.adc.intervals import MAX_N_INTERVALS, check_n_intervals
    from sb3_adc.config import validators

    n_intervals = validators.checked_by(check_n_intervals, validators.integer())
    assert n_intervals(1e2, "my.yml [Pendulum-v1]", "n_intervals") == 100
    with pytest.raises(HyperparamsError, match=rf"my\.yml \[Pendulum-v1\]: `n_intervals`: .*<= {MAX_N_INTERVALS}"):
        n_intervals(10**5, "my.yml [Pendulum-v1]", "n_intervals")
    with pytest.raises(HyperparamsError, match=r"`n_intervals`: expected an integer"):
        n_intervals("many", "my.yml [Pendulum-v1]", "n_intervals")
