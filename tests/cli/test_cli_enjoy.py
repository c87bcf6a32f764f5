"""``sb3-adc enjoy``: play a trained run, print its returns, record a GIF or a video."""

import imageio.v3 as iio
import pytest

from sb3_adc.experiment import FinalEvaluation


@pytest.fixture(scope="module")
def trained_run(tmp_path_factory, tiny_conf):
    from sb3_adc.cli import main

    logs = tmp_path_factory.mktemp("enjoy") / "logs"
    args = ["train", "--algo", "adc", "--env", "Pendulum-v1", "-conf", str(tiny_conf / "adc.yml"), "-f", str(logs)]
    assert main([*args, "--seed", "2", "-n", "200", "--eval-freq", "100", "--eval-episodes", "1", "--no-progress-bar"]) == 0
    return logs


def episode_returns(out):
    return [float(line.split("return ")[1].split(",")[0]) for line in out.splitlines() if line.startswith("Episode ")]


def test_enjoy_replays_the_final_evaluation(cli, trained_run):
    # Same seed and episode count as the final evaluation: the same returns.
    status, out, _ = cli("enjoy", "--algo", "adc", "--env", "Pendulum-v1", "-f", trained_run, "-n", 10)
    assert status == 0
    final = FinalEvaluation.load(trained_run / "adc" / "Pendulum-v1_1" / "Pendulum-v1" / "final_evaluation.json")
    assert episode_returns(out) == pytest.approx(final.returns, abs=0.01)
    assert "over 10 deterministic episodes" in out
    assert "length 50" in out


def test_enjoy_records_a_gif_and_a_video(cli, trained_run, tmp_path):
    pytest.importorskip("imageio_ffmpeg", reason="videos need the `video` extra")
    run_dir = trained_run / "adc" / "Pendulum-v1_1"
    gif, video = tmp_path / "out" / "rollout.gif", tmp_path / "rollout.mp4"
    args = ["--run-dir", run_dir, "--model", "best", "-n", 2, "--gif", gif, "--video", video, "--fps", 10]
    status, out, _ = cli("enjoy", *args)
    assert status == 0
    assert len(episode_returns(out)) == 2
    frames = iio.imread(gif, index=None)
    assert frames.shape[0] == 50
    assert frames.shape[-1] in (3, 4)
    assert video.stat().st_size > 1000
    assert "Recorded the first episode (50 frames)" in out


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--algo", "adc", "--env", "MountainCarContinuous-v0"], "no run of adc on MountainCarContinuous-v0"),
        (["--algo", "adc", "--env", "Pendulum-v1", "--exp-id", "7"], "holds no sb3-adc run"),
        (["--algo", "adc"], "give --run-dir, or --algo and --env"),
        (["--algo", "adc", "--env", "Pendulum-v1", "--model", "last-checkpoint", "-n", "0"], "-n/--n-episodes must be >= 1"),
    ],
)
def test_enjoy_errors(cli, trained_run, args, message):
    status, _, err = cli("enjoy", "-f", trained_run, *args)
    assert status == 2
    assert message in err


def test_enjoy_refuses_a_model_file_that_would_run_code(cli, trained_run, tmp_path, monkeypatch):
    # A copy of the run whose final model carries a pickled payload: enjoy's safe load refuses it (exit 2) without
    # running it; --trust-model-file unpickles it as SB3 does.
    import base64
    import json
    import os
    import shutil
    import zipfile

    import cloudpickle

    class Payload:
        def __reduce__(self):
            return (exec, ("import os; os.environ['SB3_ADC_ENJOY_PAYLOAD'] = 'ran'",))

    monkeypatch.delenv("SB3_ADC_ENJOY_PAYLOAD", raising=False)
    run_dir = tmp_path / "Pendulum-v1_1"
    shutil.copytree(trained_run / "adc" / "Pendulum-v1_1", run_dir)
    model = run_dir / "Pendulum-v1.zip"
    with zipfile.ZipFile(model) as archive:
        entries = {name: archive.read(name) for name in archive.namelist()}
    data = json.loads(entries["data"])
    data["action_noise"] = {":serialized:": base64.b64encode(cloudpickle.dumps(Payload())).decode()}
    entries["data"] = json.dumps(data).encode()
    with zipfile.ZipFile(model, "w") as archive:
        for name, content in entries.items():
            archive.writestr(name, content)
    status, _, err = cli("enjoy", "--run-dir", run_dir, "-n", 1)
    assert status == 2
    assert "`action_noise` needs `builtins.exec`" in err
    assert "SB3_ADC_ENJOY_PAYLOAD" not in os.environ
    status, _, _ = cli("enjoy", "--run-dir", run_dir, "-n", 1, "--trust-model-file")
    assert status == 0
    assert os.environ.get("SB3_ADC_ENJOY_PAYLOAD") == "ran"
