"""``sb3-adc plot --csv`` given a run folder, a run's ``evaluations.npz`` or a wrong file; one run per algorithm."""

import pytest


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory, tiny_conf):
    """One finished tiny run of ``sb3-adc train`` (300 steps, an evaluation every 100)."""
    from sb3_adc.cli import main

    logs = tmp_path_factory.mktemp("logs")
    args = ["train", "--algo", "adc", "--env", "Pendulum-v1", "-conf", str(tiny_conf / "adc.yml"), "-f", str(logs)]
    args += ["--seed", "0", "--eval-freq", "100", "--eval-episodes", "1", "--final-eval-episodes", "2"]
    assert main(args) == 0
    return logs / "adc" / "Pendulum-v1_1"


@pytest.mark.parametrize("target", ["run", "npz", "logs"])
def test_plot_reads_a_run_folder(cli, run_dir, tmp_path, target):
    csv = {"run": run_dir, "npz": run_dir / "evaluations.npz", "logs": run_dir.parent.parent}[target]
    status, _, err = cli("plot", "--csv", csv, "-o", tmp_path / "plots", "--reps", 20)
    assert status == 0, err
    assert (tmp_path / "plots" / "learning_curves.png").is_file()
    curves = (tmp_path / "plots" / "curves.csv").read_text()
    assert "adc" in curves
    # One run: the intervals and P(X > Y) mean nothing, and the command says so.
    assert "need at least 2 runs" in err
    assert "adc on Pendulum-v1" in err


def test_plot_default_output_is_in_the_run_folder(cli, run_dir):
    status, _, err = cli("plot", "--csv", run_dir, "--reps", 20)
    assert status == 0, err
    assert (run_dir / "plots" / "final_performance.csv").is_file()


def test_plot_of_a_file_that_is_not_a_table_exits_2(cli, tmp_path):
    path = tmp_path / "data.npz"
    path.write_bytes(bytes(range(256)) * 4)
    status, _, err = cli("plot", "--csv", path)
    assert status == 2
    assert "Traceback" not in err
    assert f"--csv: {path} is not a CSV table" in err
    assert "a run folder of sb3-adc train" in err


def test_plot_of_a_missing_path_or_an_empty_folder_says_what_it_accepts(cli, tmp_path):
    status, _, err = cli("plot", "--csv", tmp_path / "nothing.csv")
    assert status == 2
    assert "does not exist; --csv accepts the evaluations.csv written by sb3-adc benchmark" in err
    status, _, err = cli("plot", "--csv", tmp_path)
    assert status == 2
    assert f"{tmp_path} holds neither evaluations.csv nor runs" in err
