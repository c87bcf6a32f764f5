"""
The RL-Zoo log layout of a training run.

A run of ``algo`` on ``env_id`` lives in ``{log_folder}/{algo}/{env_name}_{run_id}/`` (``env_name`` is the
id with ``/`` replaced by ``-``, ``run_id`` counts from 1), holding::

    {env_name}.zip                          final model
    best_model.zip                          best model of the periodic evaluations
    evaluations.npz                         periodic evaluations (timesteps, results, ep_lengths)
    0.monitor.csv, 1.monitor.csv, ...       training episodes of each environment
    rl_model_{t}_steps.zip                  checkpoint: model at timestep t
    rl_model_replay_buffer_{t}_steps.pkl    checkpoint: replay buffer
    rl_model_vecnormalize_{t}_steps.pkl     checkpoint: VecNormalize statistics (with `normalize`)
    rl_model_continuation_{t}_steps.pkl     checkpoint: what makes a resume exact (generators, episodes ...)
    rl_model_manifest_{t}_steps.json        checkpoint: size and SHA-256 of each of its files, written last
    {env_name}/config.yml                   the resolved hyperparameters
    {env_name}/args.yml                     the run settings (algorithm, seed, budget, evaluation ...)
    {env_name}/vecnormalize.pkl             final VecNormalize statistics (with `normalize`)
    {env_name}/final_evaluation.json        the final evaluation; written last: the run is finished
    .lock                                   held by the one process writing the run (:class:`FolderLock`)
"""

from __future__ import annotations

import contextlib
import errno
import glob
import os
import re
import sys
import warnings
from collections.abc import Iterable
from dataclasses import dataclass
from types import TracebackType

CHECKPOINT_PREFIX = "rl_model"
_CHECKPOINT_PATTERN = re.compile(rf"^{CHECKPOINT_PREFIX}_(\d+)_steps\.zip$")
#: The lock file of a run folder, and of a benchmark's log folder (:class:`FolderLock`).
LOCK_FILE = ".lock"
#: Where Windows locks its byte of the lock file: past the holder's PID, which others read.
_WINDOWS_LOCK_OFFSET = 1 << 20


class RunLocked(RuntimeError):
    """
    Another process is writing the folder (exit status 2 at the CLI).

    :param folder: The locked folder
    :param pid: The process holding the lock, if it wrote its PID
    :param activity: What the holder is doing with the folder, e.g. ``"training it"``
    """

    def __init__(self, folder: str, pid: int | None, activity: str = "training it"):
        holder = "another process" if pid is None else f"another process (PID {pid})"
        super().__init__(
            f"{folder} is in use: {holder} is {activity}. Wait for it to end (or stop it), then run this again; "
            "a process that died has released the folder already."
        )
        self.folder = folder
        self.pid = pid


class FolderLock:
    """
    An exclusive OS lock on a folder's :data:`LOCK_FILE`, taken without waiting (``fcntl.flock``, ``msvcrt.locking``
    on Windows; none, with a warning, where the platform or file system has none). The file holds the holder's PID
    and is never deleted: the OS releases the lock when its holder ends, however it ends (``kill -9`` included).
    Two locks of one process are two holders. A context manager.

    :param folder: The folder (created if needed)
    :param activity: What the holder does with the folder, for the error of a second one (see :class:`RunLocked`)
    """

    def __init__(self, folder: str, activity: str = "training it"):
        self.folder = folder
        self.activity = activity
        self.path = os.path.join(folder, LOCK_FILE)
        self._fd: int | None = None

    @property
    def held(self) -> bool:
        """Whether this object holds the lock (``False`` also where the platform has none)."""
        return self._fd is not None

    def acquire(self) -> None:
        """
        Take the lock, or fail at once.

        :raises RunLocked: if another process (or another :class:`FolderLock` of this one) holds it
        :raises RuntimeError: if this object holds it already
        """
        if self._fd is not None:
            raise RuntimeError(f"{self.path} is already held by this lock.")
        os.makedirs(self.folder, exist_ok=True)
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        locked: bool | None = False
        try:
            locked = _try_lock(fd)
        finally:
            if not locked:
                os.close(fd)
        if locked is False:
            raise RunLocked(self.folder, self.holder_pid(), self.activity)
        if locked is None:
            return
        self._fd = fd
        with contextlib.suppress(OSError):  # the PID only helps the message of a second writer
            pid = f"{os.getpid()}\n".encode()
            os.lseek(fd, 0, os.SEEK_SET)
            os.write(fd, pid)
            os.ftruncate(fd, len(pid))

    def release(self) -> None:
        """Release the lock (nothing if this object does not hold it); the file stays."""
        fd, self._fd = self._fd, None
        if fd is not None:
            try:
                _unlock(fd)
            finally:
                os.close(fd)

    def holder_pid(self) -> int | None:
        """The PID the holder wrote in the lock file (``None`` if unreadable or not written yet)."""
        try:
            with open(self.path, encoding="ascii", errors="replace") as stream:
                text = stream.read(32).strip()
        except OSError:
            return None
        return int(text) if text.isdigit() else None

    def __enter__(self) -> FolderLock:
        self.acquire()
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, traceback: TracebackType | None
    ) -> None:
        self.release()


def _try_lock(fd: int) -> bool | None:
    """Lock without waiting: ``True``, ``False`` (another holder has it) or ``None`` (no locks here, after a warning)."""
    if sys.platform == "win32":
        import msvcrt

        os.lseek(fd, _WINDOWS_LOCK_OFFSET, os.SEEK_SET)
        try:
            msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
        except OSError:
            return False
        return True
    try:
        import fcntl
    except ImportError:
        warnings.warn("this platform has no file locks: nothing stops two processes writing one run.", stacklevel=3)
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    except OSError as error:
        if error.errno not in (errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS):
            raise
        warnings.warn(f"the file system refuses locks ({error}): nothing stops two processes writing one run.", stacklevel=3)
        return None
    return True


def _unlock(fd: int) -> None:
    if sys.platform == "win32":
        import msvcrt

        os.lseek(fd, _WINDOWS_LOCK_OFFSET, os.SEEK_SET)
        msvcrt.locking(fd, msvcrt.LK_UNLCK, 1)
        return
    import fcntl

    fcntl.flock(fd, fcntl.LOCK_UN)


class DamagedFileError(ValueError):
    """
    A file of a run cannot be read (truncated or corrupted).

    :param path: The file
    :param reason: What is wrong with it
    """

    def __init__(self, path: str, reason: str):
        super().__init__(f"{path} is damaged: {reason}")
        self.path = path
        self.reason = reason


def remove_files(paths: Iterable[str]) -> None:
    """Delete those of ``paths`` that exist."""
    for path in paths:
        with contextlib.suppress(FileNotFoundError):
            os.remove(path)


def env_name(env_id: str) -> str:
    """
    The environment's name in paths: the id with ``/`` replaced by ``-`` (as the RL Zoo).

    :param env_id: The Gymnasium id
    """
    return env_id.replace("/", "-")


def run_ids(log_folder: str, algo: str, env_id: str) -> list[int]:
    """
    The run ids of the existing runs of ``algo`` on ``env_id``, sorted.

    :param log_folder: The log folder
    :param algo: The algorithm's name
    :param env_id: The environment id
    """
    prefix = env_name(env_id) + "_"
    paths = glob.glob(os.path.join(glob.escape(os.path.join(log_folder, algo)), glob.escape(prefix) + "[0-9]*"))
    suffixes = [os.path.basename(path)[len(prefix) :] for path in paths if os.path.isdir(path)]
    return sorted(int(suffix) for suffix in suffixes if suffix.isdigit())


def new_run_dir(log_folder: str, algo: str, env_id: str) -> str:
    """
    Create the folder of a new run with the next free run id (claimed with ``os.mkdir``, so that runs started at
    once into one log folder each get their own), and return it.

    :param log_folder: The log folder
    :param algo: The algorithm's name
    :param env_id: The environment id
    """
    os.makedirs(os.path.join(log_folder, algo), exist_ok=True)
    run_id = 0
    while True:  # the next id, until one is not claimed by another run (or a file)
        ids = run_ids(log_folder, algo, env_id)
        run_id = max(run_id + 1, (ids[-1] if ids else 0) + 1)
        run_dir = os.path.join(log_folder, algo, f"{env_name(env_id)}_{run_id}")
        with contextlib.suppress(FileExistsError):
            os.mkdir(run_dir)
            return run_dir


def latest_run_dir(log_folder: str, algo: str, env_id: str) -> str | None:
    """
    The folder of the latest run (highest run id), or ``None`` if there is none.

    :param log_folder: The log folder
    :param algo: The algorithm's name
    :param env_id: The environment id
    """
    ids = run_ids(log_folder, algo, env_id)
    return os.path.join(log_folder, algo, f"{env_name(env_id)}_{ids[-1]}") if ids else None


@dataclass(frozen=True)
class Checkpoint:
    """
    The files of one checkpoint.

    :param timesteps: The timestep it was taken at
    :param model: The model zip
    :param replay_buffer: The replay buffer pickle (off-policy algorithms)
    :param vecnormalize: The VecNormalize statistics pickle (runs with ``normalize``)
    :param continuation: What an exact resume needs (:mod:`sb3_adc.experiment.continuation`), where one is
    :param manifest: The size and SHA-256 of each of the others (:mod:`sb3_adc.experiment.manifest`), written last
    """

    timesteps: int
    model: str
    replay_buffer: str
    vecnormalize: str
    continuation: str
    manifest: str

    @property
    def files(self) -> tuple[str, ...]:
        """All the checkpoint's paths (present or not), the model zip first, the manifest last."""
        return (self.model, self.replay_buffer, self.vecnormalize, self.continuation, self.manifest)

    def remove(self) -> None:
        """Delete the checkpoint's files that exist."""
        remove_files(self.files)


class _RunPath:
    """A path in a run's folder, read as an attribute of :class:`RunLayout` (``{env}``: :func:`env_name`)."""

    def __init__(self, *parts: str):
        self.parts = parts

    def __get__(self, layout: RunLayout, owner: type | None = None) -> str:
        name = env_name(layout.env_id)
        return os.path.join(layout.run_dir, *(part.format(env=name) for part in self.parts))


@dataclass(frozen=True)
class RunLayout:
    """
    The paths of one run.

    :param run_dir: The run's folder
    :param env_id: The environment id
    """

    run_dir: str
    env_id: str

    params_dir = _RunPath("{env}")  # configuration, statistics and final evaluation
    final_model = _RunPath("{env}.zip")
    best_model = _RunPath("best_model.zip")
    evaluations = _RunPath("evaluations.npz")
    config = _RunPath("{env}", "config.yml")
    args = _RunPath("{env}", "args.yml")
    vecnormalize = _RunPath("{env}", "vecnormalize.pkl")
    final_evaluation = _RunPath("{env}", "final_evaluation.json")

    def monitor_files(self) -> list[str]:
        """The existing monitor CSVs, by environment index."""
        files = glob.glob(os.path.join(glob.escape(self.run_dir), "*.monitor.csv"))
        return sorted(files, key=lambda path: int(os.path.basename(path).split(".")[0]))

    def checkpoint(self, timesteps: int) -> Checkpoint:
        """The files of the checkpoint at a timestep."""
        kinds = ("", "replay_buffer_", "vecnormalize_", "continuation_", "manifest_")
        names = [f"{CHECKPOINT_PREFIX}_{kind}{timesteps}_steps" for kind in kinds]
        extensions = (".zip", ".pkl", ".pkl", ".pkl", ".json")
        return Checkpoint(timesteps, *(os.path.join(self.run_dir, n + ext) for n, ext in zip(names, extensions, strict=True)))

    def checkpoints(self) -> list[Checkpoint]:
        """The checkpoints present, oldest first."""
        names = os.listdir(self.run_dir) if os.path.isdir(self.run_dir) else []
        matches = [_CHECKPOINT_PATTERN.match(name) for name in names]
        return [self.checkpoint(steps) for steps in sorted(int(match.group(1)) for match in matches if match)]

    def is_finished(self) -> bool:
        """Whether the run completed (its final evaluation is written last)."""
        return os.path.isfile(self.final_evaluation)

    def lock(self) -> FolderLock:
        """The run's lock (:class:`FolderLock`, not taken yet): one process writes the run at a time."""
        return FolderLock(self.run_dir, "training it")
