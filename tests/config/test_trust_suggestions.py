"""A misspelt hyperparameter key gets a "did you mean" suggestion, in the loader and at the command line."""

import pytest

from sb3_adc.cli import main
from sb3_adc.config import HyperparamsError, load_hyperparams


def test_misspelt_key_suggests_the_close_ones():
    with pytest.raises(HyperparamsError, match=r"accepted keys: .*; did you mean `learning_rate`"):
        load_hyperparams("adc", "Pendulum-v1", overrides={"learning_rat": 0.001})


def test_unrelated_key_suggests_nothing():
    with pytest.raises(HyperparamsError) as caught:
        load_hyperparams("adc", "Pendulum-v1", overrides={"zzzz": 1})
    assert "did you mean" not in str(caught.value)


def test_misspelt_normalize_keyword_suggests_the_close_one():
    with pytest.raises(HyperparamsError, match=r"normalize\.norm_ob.*did you mean `norm_obs`"):
        load_hyperparams("ddpg", "Pendulum-v1", overrides={"normalize": {"norm_ob": True}})


def test_cli_names_the_suggestion_and_exits_2(capsys, tmp_path):
    status = main(["train", "--algo", "adc", "--env", "Pendulum-v1", "-params", "learning_rat:0.001", "-f", str(tmp_path)])
    assert status == 2
    err = capsys.readouterr().err
    assert "did you mean `learning_rate`" in err
    assert "Traceback" not in err
    assert not list(tmp_path.iterdir())
