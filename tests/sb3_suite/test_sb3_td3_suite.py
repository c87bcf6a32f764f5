"""
Stable-Baselines3's own TD3 tests, run against ADC and against the ``td3`` of every comparison
(:class:`~sb3_adc.baselines.AveragedActorTD3` with the averaged actor on).

The tests come from the source distribution of the installed ``stable-baselines3`` version (the one
``constraints.txt`` pins), downloaded once with ``pip download`` into ``.cache/sb3-tests/`` (ignored by git);
nothing of SB3 is vendored. They run in a separate pytest process with the :mod:`td3_as_adc` plugin, which
rebinds ``stable_baselines3.TD3`` to the class under test and keeps only the tests that exercise it. Without network access and
without the cache the test is skipped, saying why; ``SB3_ADC_SB3_SDIST`` may name an sdist downloaded beforehand.

:data:`SB3_TEST_MODULES` are the modules run by default (about a minute on one core);
``SB3_ADC_SB3_SUITE=all`` runs every SB3 module that exercises TD3 (:data:`ALL_TD3_MODULES`, several minutes).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tarfile
import tempfile
from importlib import metadata
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
REPOSITORY = HERE.parent.parent
CACHE = REPOSITORY / ".cache" / "sb3-tests"

#: SB3 test modules run by default: training, prediction, train/eval mode, callbacks, saving and loading.
SB3_TEST_MODULES = ("test_run.py", "test_predict.py", "test_train_eval_mode.py", "test_callbacks.py", "test_save_load.py")
#: Every SB3 test module that exercises TD3 (``SB3_ADC_SB3_SUITE=all``).
ALL_TD3_MODULES = (
    *SB3_TEST_MODULES,
    "test_cnn.py",
    "test_custom_policy.py",
    "test_deterministic.py",
    "test_dict_env.py",
    "test_her.py",
    "test_identity.py",
    "test_n_step_replay.py",
    "test_spaces.py",
    "test_tensorboard.py",
    "test_vec_normalize.py",
)
#: The default modules hold more TD3 tests than this; fewer collected means the rebinding or the selection broke.
MIN_TESTS_RUN = 15


def sb3_version() -> str:
    return metadata.version("stable-baselines3")


def download_sdist(version: str, folder: Path) -> Path:
    """The sdist of ``stable-baselines3==version``, from ``SB3_ADC_SB3_SDIST`` or ``pip download``; skips when offline."""
    given = os.environ.get("SB3_ADC_SB3_SDIST")
    if given:
        return Path(given)
    command = [
        sys.executable,
        "-m",
        "pip",
        "download",
        "--no-deps",
        "--no-binary",
        ":all:",
        "--disable-pip-version-check",
        f"stable-baselines3=={version}",
        "-d",
        str(folder),
    ]
    try:
        result = subprocess.run(command, capture_output=True, text=True, timeout=180, check=False)
    except subprocess.TimeoutExpired:
        pytest.skip(f"SB3's tests not run: `pip download stable-baselines3=={version}` timed out (offline?)")
    archives = sorted(folder.glob("stable_baselines3-*.tar.gz"))
    if result.returncode != 0 or not archives:
        reason = (result.stderr.strip().splitlines() or ["no output"])[-1]
        pytest.skip(f"SB3's tests not run: could not download the stable-baselines3=={version} sdist (offline?): {reason}")
    return archives[0]


def sb3_tests(version: str) -> Path:
    """The folder of the sdist's ``tests/`` (its parent holds the sdist's pytest configuration), fetched once."""
    root = CACHE / f"stable_baselines3-{version}"
    if (root / "tests").is_dir():
        return root
    CACHE.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=CACHE) as scratch:
        archive = download_sdist(version, Path(scratch))
        extracted = Path(scratch) / "extracted"
        with tarfile.open(archive) as sdist:
            prefix = f"stable_baselines3-{version}/"
            wanted = [
                member
                for member in sdist.getmembers()
                if member.name.startswith(prefix + "tests/") or member.name == prefix + "pyproject.toml"
            ]
            if hasattr(tarfile, "data_filter"):
                sdist.extractall(extracted, members=wanted, filter="data")
            else:  # Python < 3.10.12 / 3.11.4: check by hand what the "data" filter checks
                unsafe = [m.name for m in wanted if not (m.isfile() or m.isdir()) or ".." in Path(m.name).parts]
                if unsafe:
                    pytest.fail(f"unexpected entries in the stable-baselines3 sdist: {unsafe}")
                sdist.extractall(extracted, members=wanted)
        try:
            # Atomic: another test process may be fetching the same version.
            os.replace(extracted / f"stable_baselines3-{version}", root)
        except OSError:
            if not (root / "tests").is_dir():
                raise
    return root


@pytest.mark.slow
@pytest.mark.parametrize("under_test", ["adc", "averaged_td3"])
def test_sb3_td3_tests_pass(tmp_path, under_test):
    version = sb3_version()
    root = sb3_tests(version)
    modules = ALL_TD3_MODULES if os.environ.get("SB3_ADC_SB3_SUITE") == "all" else SB3_TEST_MODULES
    missing = [name for name in modules if not (root / "tests" / name).is_file()]
    assert not missing, f"SB3 {version}'s sdist has no {missing}: update SB3_TEST_MODULES"
    environment = dict(
        os.environ,
        PYTHONPATH=os.pathsep.join(filter(None, [str(HERE), os.environ.get("PYTHONPATH")])),
        OMP_NUM_THREADS="1",  # one core: the suite shares the machine with the other tests
        SB3_ADC_SUITE_CLASS=under_test,
    )
    command = [
        sys.executable,
        "-m",
        "pytest",
        *(str(root / "tests" / name) for name in modules),
        "-p",
        "td3_as_adc",
        "-p",
        "no:randomly",
        "-p",
        "no:xdist",
        "-p",
        "no:cacheprovider",
        "-c",
        str(root / "pyproject.toml"),
        "--rootdir",
        str(root),
        "-q",
        "-rfE",
        "--basetemp",
        str(tmp_path / "basetemp"),
    ]
    # The SB3 tests write logs relative to the working directory: keep them out of the repository and the cache.
    result = subprocess.run(command, cwd=tmp_path, env=environment, capture_output=True, text=True, timeout=1200, check=False)
    output = result.stdout + result.stderr
    assert result.returncode == 0, f"SB3 {version}'s TD3 tests fail with {under_test}:\n{output[-6000:]}"
    passed = re.search(r"(\d+) passed", output)
    assert passed is not None, output[-3000:]
    assert int(passed.group(1)) >= MIN_TESTS_RUN, output[-3000:]


def test_without_network_the_suite_is_skipped_with_the_reason(monkeypatch, tmp_path):
    monkeypatch.delenv("SB3_ADC_SB3_SDIST", raising=False)
    monkeypatch.setenv("PIP_INDEX_URL", "http://127.0.0.1:9/simple")  # nothing listens on the discard port
    monkeypatch.setenv("PIP_NO_CACHE_DIR", "1")
    monkeypatch.setenv("PIP_RETRIES", "0")
    monkeypatch.setenv("PIP_TIMEOUT", "2")
    monkeypatch.delenv("PIP_FIND_LINKS", raising=False)
    with pytest.raises(pytest.skip.Exception, match=r"could not download the stable-baselines3==\S+ sdist \(offline\?\)"):
        download_sdist(sb3_version(), tmp_path)
