"""Tuning storages, worker counts and a full disk end in exit-2 messages naming the option or file, not tracebacks."""

import errno
import os

import pytest

from sb3_adc.common import atomic
from sb3_adc.config import HyperparamsError
from sb3_adc.experiment.tuning import TuneSettings
from sb3_adc.experiment.tuning_storage import check_storage


def tune_args(train_args, log_folder, *extra):
    return [*train_args("ddpg", log_folder), "-optimize", "--n-trials", 1, "--n-evaluations", 2, *extra]


@pytest.mark.parametrize(
    ("storage", "message"),
    [
        ("foo://bar", "foo://bar: unknown database 'foo'; accepted: a journal file (*.log) or a database URL"),
        ("sqlite:////nonexistent-sb3-adc/x.db", "sqlite:////nonexistent-sb3-adc/x.db: the folder /nonexistent-sb3-adc of"),
        ("{tmp}", "{tmp} is a folder; it must be a journal file"),
        ("sqlite:///{tmp}", "sqlite:///{tmp} is a folder; it must be a SQLite database file"),
        ("/dev/zero", "/dev/zero is not a regular file; it must be a journal file"),
        ("sqlite:///:memory:", "sqlite:///:memory:: an SQLite database in memory cannot be shared or resumed"),
    ],
)
def test_bad_storage_exits_2_naming_it_before_writing(cli, train_args, tmp_path, storage, message):
    logs = tmp_path / "logs"
    status, _, err = cli(*tune_args(train_args, logs, "--storage", storage.format(tmp=tmp_path)))
    assert status == 2, err
    assert f"`--storage`: {message.format(tmp=tmp_path)}" in err
    assert "Traceback" not in err
    assert not logs.exists()


@pytest.mark.parametrize(
    "url",
    ["mysql://tuner:s3cret-pw@127.0.0.1:9/optuna", "postgresql+psycopg2://tuner:s3cret-pw@127.0.0.1:9/optuna"],
)
def test_database_errors_never_show_the_password(cli, train_args, tmp_path, url):
    logs = tmp_path / "logs"
    status, out, err = cli(*tune_args(train_args, logs, "--storage", url))
    assert status == 2, err
    assert "`--storage`" in err
    assert "tuner:***@127.0.0.1" in err
    assert "s3cret-pw" not in err + out
    assert not logs.exists()


def test_a_file_that_is_no_journal_is_refused(cli, train_args, tmp_path):
    journal = tmp_path / "study.log"
    journal.write_bytes(b'{"not": "optuna"}\n')
    status, _, err = cli(*tune_args(train_args, tmp_path / "logs", "--storage", journal))
    assert status == 2, err
    assert f"`--storage`: {journal}: cannot open the study" in err


def test_good_storages_pass_the_check(tmp_path):
    check_storage(str(tmp_path / "new.log"))
    (tmp_path / "old.log").write_text("")
    check_storage(str(tmp_path / "old.log"))
    check_storage(f"sqlite:///{tmp_path / 'study.db'}")
    check_storage("postgresql://user:pw@host/db")  # databases are checked when opened


def test_n_jobs_is_bounded_by_the_cpus(cli, train_args, tmp_path):
    limit = 2 * (os.cpu_count() or 1)
    with pytest.raises(HyperparamsError, match=rf"`--n-jobs`: must be an integer in \[1, {limit}\] \(2 per CPU"):
        TuneSettings(algo="ddpg", env_id="Pendulum-v1", n_jobs=limit + 1)
    logs = tmp_path / "logs"
    status, _, err = cli(*tune_args(train_args, logs, "--n-jobs", 1000))
    assert status == 2
    assert "`--n-jobs`: must be an integer in [1, " in err
    assert not logs.exists()


class FullDisk:
    """The ``os`` module, but every ``fsync`` fails as on a full disk (an error that names no file)."""

    def __getattr__(self, name):
        return getattr(os, name)

    @staticmethod
    def fsync(descriptor):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def test_a_failed_atomic_write_names_its_file(tmp_path, monkeypatch):
    monkeypatch.setattr(atomic, "os", FullDisk())
    target = tmp_path / "table.csv"
    with pytest.raises(OSError, match="No space left on device") as caught:
        atomic.write_atomically(target, lambda stream: stream.write("a,b\n"))
    assert caught.value.filename == str(target)
    assert not target.exists()
    assert not list(tmp_path.iterdir())  # the temporary file is gone too


def test_a_full_disk_exits_2_naming_the_file(cli, train_args, tmp_path, monkeypatch):
    monkeypatch.setattr(atomic, "os", FullDisk())
    logs = tmp_path / "logs"
    status, _, err = cli(*train_args("ddpg", logs))
    assert status == 2, err
    assert "Traceback" not in err
    assert f"sb3-adc train: error: {logs / 'ddpg' / 'Pendulum-v1_1'}" in err
    assert err.rstrip().endswith(": No space left on device")


def test_other_os_errors_still_raise(cli, train_args, tmp_path, monkeypatch):
    class Broken(FullDisk):
        @staticmethod
        def fsync(descriptor):
            raise OSError(errno.EBADF, os.strerror(errno.EBADF))

    monkeypatch.setattr(atomic, "os", Broken())
    with pytest.raises(OSError, match="Bad file descriptor"):
        cli(*train_args("ddpg", tmp_path / "logs"))


def test_memory_exhausted_exits_2_saying_what_sizes_it(cli, train_args, tmp_path, monkeypatch):
    from sb3_adc.cli import train_command

    def allocate(settings, **_):
        raise MemoryError("Unable to allocate 186. GiB for an array with shape (50000, 1, 1000000) and data type float32")

    monkeypatch.setattr(train_command, "train", allocate)
    status, _, err = cli(*train_args("ddpg", tmp_path / "logs"))
    assert status == 2
    assert "Traceback" not in err
    assert "error: out of memory (Unable to allocate 186. GiB" in err
    assert "lower buffer_size, batch_size, n_envs" in err
