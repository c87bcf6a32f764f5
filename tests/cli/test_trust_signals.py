"""A scheduler's SIGTERM (Slurm, Kubernetes) stops ``sb3-adc train`` as Ctrl-C does: checkpoint, status 130."""

import os
import re
import signal
import subprocess
import sys
import threading
import time

import pytest

from sb3_adc.experiment.training import sigterm_as_sigint

pytestmark = pytest.mark.skipif(os.name == "nt", reason="POSIX signals")


def test_sigterm_saves_a_checkpoint_exits_130_and_resume_continues(cli, tmp_path, tiny_conf):
    logs = tmp_path / "logs"
    command = [sys.executable, "-m", "sb3_adc", "train", "--algo", "adc", "--env", "Pendulum-v1", "-f", str(logs)]
    command += ["-conf", str(tiny_conf / "adc.yml"), "-n", "100000", "--eval-freq", "100", "--eval-episodes", "1"]
    command += ["--seed", "1", "--no-progress-bar"]
    process = subprocess.Popen(command, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    run_dir = logs / "adc" / "Pendulum-v1_1"
    try:
        deadline = time.monotonic() + 120
        while not (run_dir / "rl_model_200_steps.zip").exists():
            assert process.poll() is None, process.stderr.read().decode()
            assert time.monotonic() < deadline, "no checkpoint after 120 s"
            time.sleep(0.1)
        process.send_signal(signal.SIGTERM)
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 130, err.decode()
    assert "Traceback" not in err.decode()
    assert "Continue with: sb3-adc train --resume" in out.decode()
    checkpoint = max(int(path.name.split("_")[2]) for path in run_dir.glob("rl_model_[0-9]*_steps.zip"))
    assert checkpoint >= 200
    status, out, err = cli("train", "--resume", run_dir, "-n", checkpoint + 100)
    assert status == 0, err
    assert f"from timestep {checkpoint} of {checkpoint + 100}" in out
    assert (run_dir / "Pendulum-v1.zip").is_file()


def test_sigterm_outside_training_raises_keyboard_interrupt_and_the_handler_is_restored():
    before = signal.getsignal(signal.SIGTERM)

    def signal_and_wait():
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(1)

    with sigterm_as_sigint(), pytest.raises(KeyboardInterrupt):
        signal_and_wait()
    assert signal.getsignal(signal.SIGTERM) is before


def test_sigterm_stops_a_process_started_with_sigint_ignored():
    """A shell script's background job (``sb3-adc train ... &``) starts with SIGINT ignored: SIGTERM still stops it."""
    code = (
        "import os, signal, time\n"
        "from sb3_adc.experiment.training import sigterm_as_sigint\n"
        "assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN\n"
        "try:\n"
        "    with sigterm_as_sigint():\n"
        "        os.kill(os.getpid(), signal.SIGTERM)\n"
        "        time.sleep(5)\n"
        "except KeyboardInterrupt:\n"
        "    print('stopped')\n"
    )
    ignore_sigint = lambda: signal.signal(signal.SIGINT, signal.SIG_IGN)  # noqa: E731
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, preexec_fn=ignore_sigint
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "stopped"


def test_sigterm_calls_the_sigint_handler_in_place():
    calls = []
    previous_int = signal.signal(signal.SIGINT, lambda signum, frame: calls.append(signum))
    try:
        with sigterm_as_sigint():
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(0.1)
    finally:
        signal.signal(signal.SIGINT, previous_int)
    assert calls == [signal.SIGINT]


def test_nothing_changes_outside_the_main_thread():
    before = signal.getsignal(signal.SIGTERM)
    errors = []

    def body():
        try:
            with sigterm_as_sigint():
                pass
        except Exception as error:  # pragma: no cover - reported below
            errors.append(error)

    thread = threading.Thread(target=body)
    thread.start()
    thread.join()
    assert not errors
    assert signal.getsignal(signal.SIGTERM) is before


def test_benchmark_sigterm_to_the_parent_alone_stops_the_workers_with_checkpoints(tmp_path, tiny_conf):
    """As Kubernetes stops a container: SIGTERM to the main process only; its workers checkpoint, none starts."""
    logs = tmp_path / "logs"
    command = [sys.executable, "-m", "sb3_adc", "benchmark", "--algos", "adc", "--envs", "Pendulum-v1"]
    command += ["--seeds", "0", "1", "2", "--workers", "2", "-n", "100000", "--conf-folder", str(tiny_conf)]
    command += ["-f", str(logs), "--eval-freq", "100", "--eval-episodes", "1"]
    process = subprocess.Popen(command, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)
    try:
        deadline = time.monotonic() + 180
        while len(list(logs.glob("adc/*/rl_model_200_steps.zip"))) < 2:
            assert process.poll() is None, process.stderr.read().decode()
            assert time.monotonic() < deadline, "no checkpoints after 180 s"
            time.sleep(0.1)
        process.send_signal(signal.SIGTERM)
        out, err = process.communicate(timeout=90)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    assert process.returncode == 130, err.decode()
    assert out.decode().count("resuming continues the same run") == 2
    # Each worker's interrupt checkpoint is on disk, at or past the periodic one the signal waited for (at it when
    # the signal lands in the step that wrote it).
    saved = sorted(int(step) for step in re.findall(r"checkpoint at timestep (\d+) saved", out.decode()))
    assert len(saved) == 2, out.decode()
    assert min(saved) >= 200
    on_disk = {int(path.name.split("_")[2]) for path in logs.glob("adc/Pendulum-v1_seed[01]/rl_model_[0-9]*_steps.zip")}
    assert set(saved) <= on_disk
    assert not (logs / "adc" / "Pendulum-v1_seed2").exists(), "no run starts after the interrupt"
