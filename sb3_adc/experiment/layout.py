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
    rl_model_continuation_{t}_steps.pkl     checkpoint: what makes the resumed run the same run (random
                                            generators, episodes in progress, the step in progress)
    rl_model_manifest_{t}_steps.json        checkpoint: size and SHA-256 of each of its files, written last
    {env_name}/config.yml                   the resolved hyperparameters
    {env_name}/args.yml                     the run settings (algorithm, seed, budget, evaluation ...)
    {env_name}/vecnormalize.pkl             final VecNormalize statistics (with `normalize`)
    {env_name}/final_evaluation.json        the final evaluation; written last: the run is finished
    .lock                                   held by the process writing the run (:class:`FolderLock`)

One process writes a run at a time: :func:`~sb3_adc.experiment.training.train` and
:func:`~sb3_adc.experiment.training.resume` hold the run's :class:`FolderLock` (an OS lock on ``.lock``) for the
run's whole life, and a second writer gets :class:`RunLocked` before it writes anything. The OS releases the lock
when its process ends, however it ends (``kill -9`` included), so a crashed run can be resumed at once.
"""

from __future__ import annotations

import errno
import glob
import os
import re
import sys
import warnings
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
    Another process is writing the folder (a user error: exit status 2 at the CLI): two processes training one run
    at once would interleave their checkpoints, episodes and evaluations.

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
    An exclusive OS lock on a folder's :data:`LOCK_FILE`, taken without waiting: ``fcntl.flock`` (``msvcrt.locking``
    on Windows; no lock, with a warning, where neither exists or the file system refuses locks). The file is
    created if needed, holds the holder's PID, and is never deleted: the OS releases the lock when the holder
    closes it or ends, however it ends. One process holding the lock twice counts as two holders. A context
    manager.

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
        try:
            locked = _try_lock(fd)
        except BaseException:
            os.close(fd)
            raise
        if locked is None:
            os.close(fd)
            return
        if not locked:
            os.close(fd)
            raise RunLocked(self.folder, self.holder_pid(), self.activity)
        self._fd = fd
        try:
            os.lseek(fd, 0, os.SEEK_SET)
            os.write(fd, f"{os.getpid()}\n".encode())
            os.ftruncate(fd, len(f"{os.getpid()}\n"))
        except OSError:
            pass  # the PID only helps the message of a second writer

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
    """
    Lock an open file without waiting: ``True`` when locked, ``False`` when another holder has it, ``None`` when
    this platform or file system has no lock (after a warning: the run goes on unprotected, as before).
    """
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
    """Release the lock :func:`_try_lock` took (closing the file releases it too, the OS's way after a crash)."""
    if sys.platform == "win32":
        import msvcrt

        os.lseek(fd, _WINDOWS_LOCK_OFFSET, os.SEEK_SET)
        msvcrt.locking(fd, msvcrt.LK_UNLCK, 1)
        return
    import fcntl

    fcntl.flock(fd, fcntl.LOCK_UN)


class DamagedFileError(ValueError):
    """
    A file of a run cannot be read (truncated or corrupted, e.g. by a crash while it was written).

    :param path: The file
    :param reason: What is wrong with it
    """

    def __init__(self, path: str, reason: str):
        super().__init__(f"{path} is damaged: {reason}")
        self.path = path
        self.reason = reason


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
    folder = os.path.join(log_folder, algo)
    ids = []
    for path in glob.glob(os.path.join(glob.escape(folder), glob.escape(prefix) + "[0-9]*")):
        suffix = os.path.basename(path)[len(prefix) :]
        if suffix.isdigit() and os.path.isdir(path):
            ids.append(int(suffix))
    return sorted(ids)


def new_run_dir(log_folder: str, algo: str, env_id: str) -> str:
    """
    Create the folder of a new run, with the next free run id, and return it.

    The folder is claimed with ``os.mkdir``, which fails if it exists: of runs started at the same time into
    one log folder, each gets its own folder (the next id is tried until one is free).

    :param log_folder: The log folder
    :param algo: The algorithm's name
    :param env_id: The environment id
    """
    os.makedirs(os.path.join(log_folder, algo), exist_ok=True)
    run_id = 1
    while True:
        ids = run_ids(log_folder, algo, env_id)
        run_id = max(run_id, (ids[-1] if ids else 0) + 1)
        run_dir = os.path.join(log_folder, algo, f"{env_name(env_id)}_{run_id}")
        try:
            os.mkdir(run_dir)
        except FileExistsError:
            run_id += 1  # another run claimed this id (or a file has this name): try the next one
            continue
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
    :param continuation: What an exact resume needs (:mod:`sb3_adc.experiment.continuation`; absent where none
        is exact)
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
        for path in self.files:
            if os.path.exists(path):
                os.remove(path)


@dataclass(frozen=True)
class RunLayout:
    """
    The paths of one run.

    :param run_dir: The run's folder
    :param env_id: The environment id
    """

    run_dir: str
    env_id: str

    @property
    def params_dir(self) -> str:
        """``{run_dir}/{env_name}``: configuration, statistics and final evaluation."""
        return os.path.join(self.run_dir, env_name(self.env_id))

    @property
    def final_model(self) -> str:
        return os.path.join(self.run_dir, f"{env_name(self.env_id)}.zip")

    @property
    def best_model(self) -> str:
        return os.path.join(self.run_dir, "best_model.zip")

    @property
    def evaluations(self) -> str:
        return os.path.join(self.run_dir, "evaluations.npz")

    @property
    def config(self) -> str:
        return os.path.join(self.params_dir, "config.yml")

    @property
    def args(self) -> str:
        return os.path.join(self.params_dir, "args.yml")

    @property
    def vecnormalize(self) -> str:
        return os.path.join(self.params_dir, "vecnormalize.pkl")

    @property
    def final_evaluation(self) -> str:
        return os.path.join(self.params_dir, "final_evaluation.json")

    def monitor_file(self, rank: int) -> str:
        """
        The monitor CSV of one training environment (SB3's ``Monitor`` adds ``.monitor.csv``).

        :param rank: The environment's index
        """
        return os.path.join(self.run_dir, str(rank))

    def monitor_files(self) -> list[str]:
        """The existing monitor CSVs, by environment index."""
        files = glob.glob(os.path.join(glob.escape(self.run_dir), "*.monitor.csv"))
        return sorted(files, key=lambda path: int(os.path.basename(path).split(".")[0]))

    def checkpoint(self, timesteps: int) -> Checkpoint:
        """
        The files of the checkpoint at a timestep.

        :param timesteps: The timestep
        """

        def path(kind: str, extension: str) -> str:
            return os.path.join(self.run_dir, f"{CHECKPOINT_PREFIX}_{kind}{timesteps}_steps.{extension}")

        return Checkpoint(
            timesteps,
            path("", "zip"),
            path("replay_buffer_", "pkl"),
            path("vecnormalize_", "pkl"),
            path("continuation_", "pkl"),
            path("manifest_", "json"),
        )

    def checkpoints(self) -> list[Checkpoint]:
        """The checkpoints present, oldest first."""
        steps = []
        for name in os.listdir(self.run_dir) if os.path.isdir(self.run_dir) else []:
            match = _CHECKPOINT_PATTERN.match(name)
            if match:
                steps.append(int(match.group(1)))
        return [self.checkpoint(timesteps) for timesteps in sorted(steps)]

    def is_finished(self) -> bool:
        """Whether the run completed (its final evaluation is written last)."""
        return os.path.isfile(self.final_evaluation)

    def lock(self) -> FolderLock:
        """The run's lock (:class:`FolderLock`, not taken yet): one process writes the run at a time."""
        return FolderLock(self.run_dir, "training it")
