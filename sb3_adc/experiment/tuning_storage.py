"""The Optuna storage of a study: checked before anything is written, repaired after a crash, opened, and locked."""

from __future__ import annotations

import contextlib
import itertools
import os
import re
import shutil
import stat
import warnings
from types import SimpleNamespace
from typing import Any

import optuna
from optuna.storages.journal import JournalFileBackend, JournalFileSymlinkLock
from rl_zoo3.exp_manager import ExperimentManager

from sb3_adc.experiment.layout import FolderLock
from sb3_adc.experiment.tuning_settings import TuneSettings, refused

#: Database URL schemes (``dialect`` or ``dialect+driver``) Optuna's ``RDBStorage`` opens.
DATABASE_DIALECTS = ("sqlite", "mysql", "postgresql")
# The password of a database URL (`scheme://user:password@host/...`).
_PASSWORD = re.compile(r"(?<=://)([^/@:]*):([^/@]*)@")
#: What the holder of a study folder's lock is doing, for the error of a second command.
TUNING_ACTIVITY = "tuning its study (one command per study kept in a journal file: use --n-jobs for more workers)"


def study_lock(settings: TuneSettings) -> contextlib.AbstractContextManager[Any]:
    """
    The lock :func:`~sb3_adc.experiment.tuning.tune` holds: the study folder's
    :class:`~sb3_adc.experiment.layout.FolderLock`; none for a database (``--storage`` URL), shared on purpose.

    :param settings: The study's settings
    """
    if "://" in settings.storage_url():
        return contextlib.nullcontext()
    return FolderLock(settings.study_dir, TUNING_ACTIVITY)


def repair_journal(path: str) -> str | None:
    """
    Cut a torn last line (a write cut short by a crash) off an Optuna journal file: Optuna skips it when it reads but
    appends its next record to it, making a line no read decodes. Under the journal's lock, the file is copied to
    ``{path}.torn-{n}`` (the first free ``n``) and truncated after its last newline, with a warning naming both.

    :param path: The journal file (one that does not exist is left alone)
    :return: The copy of the torn file, or ``None`` where nothing was torn
    """
    if not os.path.isfile(path) or os.path.getsize(path) == 0:
        return None
    lock = JournalFileSymlinkLock(path)
    lock.acquire()
    try:
        with open(path, "rb+") as stream:
            text = stream.read()
            if not text or text.endswith(b"\n"):
                return None
            keep = text.rfind(b"\n") + 1
            copy = next(f"{path}.torn-{n}" for n in itertools.count() if not os.path.exists(f"{path}.torn-{n}"))
            shutil.copyfile(path, copy)
            stream.truncate(keep)
            stream.flush()
            os.fsync(stream.fileno())
    finally:
        lock.release()
    warnings.warn(
        f"{path}: its last line was cut short ({len(text) - keep} bytes without a newline, a write interrupted by a "
        f"crash); it is removed so that the study can continue, and the file as it was is kept in {copy}",
        stacklevel=2,
    )
    return copy


def hide_password(text: str, url: str) -> str:
    """
    ``text`` with the password of the database URL ``url`` (``mysql://user:password@host/db``) replaced by ``***``.

    :param text: A message that may show ``url`` or its password
    :param url: The URL
    """
    match = _PASSWORD.search(url)
    return text.replace(match.group(2), "***") if match and match.group(2) else text


def check_storage(url: str) -> None:
    """
    Check ``--storage`` before anything is written: a journal file that is a regular file or does not exist yet, or a
    database URL of :data:`DATABASE_DIALECTS` (an SQLite file in an existing folder). Messages never show a password.

    :param url: The storage (a path, or a URL with ``://``)
    :raises HyperparamsError: naming ``--storage`` and what it accepts
    """
    shown, (dialect, url_sep, rest) = hide_password(url, url), url.partition("://")
    accepted = f"accepted: a journal file (*.log) or a database URL ({', '.join(f'{d}://...' for d in DATABASE_DIALECTS)})"
    path, what = url, "journal file"
    if url_sep:
        dialect = dialect.partition("+")[0]
        if dialect not in DATABASE_DIALECTS:
            raise refused("--storage", f"{shown}: unknown database {dialect!r}; {accepted}")
        if dialect != "sqlite":
            return
        path, what = rest[1:], "SQLite database file"  # sqlite:///relative.db, sqlite:////absolute.db
        if path in ("", ":memory:"):
            raise refused("--storage", f"{shown}: an SQLite database in memory cannot be shared or resumed; give a file")
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        mode = stat.S_IFREG
    except OSError as error:
        raise refused("--storage", f"{shown}: cannot be read as a {what}: {error.strerror}") from None
    if not stat.S_ISREG(mode):
        kind = "a folder" if stat.S_ISDIR(mode) else "not a regular file"
        raise refused("--storage", f"{shown} is {kind}; it must be a {what}; {accepted}")
    folder = os.path.dirname(os.path.abspath(path))
    if url_sep and not os.path.isdir(folder):
        raise refused("--storage", f"{shown}: the folder {folder} of the {what} does not exist")


def open_study(settings: TuneSettings, worker: int) -> optuna.Study:
    """
    Create or load the study, with the sampler and pruner of ``settings``.

    :param settings: The study's settings
    :param worker: The worker's number (its sampler's seed is ``settings.sampler_seed + worker``)
    :raises HyperparamsError: naming ``--storage`` for a storage that cannot be opened (no password shown)
    """
    url, seed = settings.storage_url(), settings.sampler_seed + worker
    # The Zoo's random sampler and pruners (median after `n_evaluations // 3` warm-up steps, successive halving, none);
    # not its TPE, which is multivariate: that would change the draws of committed studies.
    zoo: Any = SimpleNamespace(seed=seed, n_startup_trials=settings.n_startup_trials, n_evaluations=settings.n_evaluations)
    sampler = ExperimentManager._create_sampler(zoo, "random")
    if settings.sampler == "tpe":
        sampler = optuna.samplers.TPESampler(n_startup_trials=settings.n_startup_trials, seed=seed)
    pruner = ExperimentManager._create_pruner(zoo, settings.pruner)
    try:
        store: str | optuna.storages.BaseStorage = url  # a database: Optuna opens it (SQLAlchemy needed)
        if "://" not in url:
            os.makedirs(os.path.dirname(os.path.abspath(url)), exist_ok=True)
            store = optuna.storages.JournalStorage(JournalFileBackend(url))
        return optuna.create_study(
            storage=store, study_name=settings.name, sampler=sampler, pruner=pruner, direction="maximize", load_if_exists=True
        )
    except ImportError as error:
        raise refused("--storage", hide_password(f"{url}: {error} (a journal file `*.log` needs nothing)", url)) from None
    except Exception as error:
        # A file that is no Optuna journal (JSON it cannot decode, records without its keys), or the database's own
        # errors (SQLAlchemy's: no such server, access denied, not a database...).
        if "://" not in url and not isinstance(error, (ValueError, LookupError, TypeError)):
            raise
        message = f"{url}: cannot open the study: {type(error).__name__}: {error}"
        raise refused("--storage", hide_password(message, url)) from None
