"""
Loading a model zip without running code from it.

SB3 saves the entries of a model that JSON cannot hold (the spaces, the schedules, the policy and buffer classes,
the action noise, the last observations) as cloudpickle in the zip's ``data`` entry and unpickles them on
``load``: a model file is code, as a pickle is, and loading one from a stranger runs whatever it holds. Its
tensors are safe already (SB3 reads them with ``torch.load(weights_only=True)``).

:func:`safe_objects` reads those entries with an unpickler that builds only an allow-listed set of classes and
functions (:data:`ALLOWED`: numpy arrays and generators, Gymnasium spaces, SB3's schedules, policies, buffers and
noises, torch activations and optimizers, and this package's own classes) and refuses anything else, a function shipped
by value included, with a :class:`UnsafeModelFileError` naming the entry and what it needs. The objects go to SB3's
``load`` as ``custom_objects``, so that SB3 unpickles nothing. The restriction is the one ``torch.load`` applies
with ``weights_only=True``; cloudpickle itself has no such mode.

The pickles of a run folder (a checkpoint's replay buffer, ``VecNormalize`` statistics and continuation) are read
the same way by :func:`restricted_load`, each with an allow-list of exactly the globals such a file holds when
sb3-adc writes it (:data:`REPLAY_BUFFER_GLOBALS`, :data:`VEC_NORMALIZE_GLOBALS`, :data:`CONTINUATION_GLOBALS`): a
file planted in a run folder is refused, not run.
"""

from __future__ import annotations

import base64
import binascii
import io
import json
import pathlib
import pickle
import zipfile
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from stable_baselines3.common.vec_env import VecEnv, VecNormalize

#: Globals a safe load may build: ``module -> names`` (``"*"``: every class of the module and of its submodules,
#: for this package, whose classes run no code they are given).
ALLOWED: dict[str, frozenset[str]] = {
    "builtins": frozenset({"set", "frozenset", "slice", "complex", "bytearray", "range"}),
    "collections": frozenset({"deque", "OrderedDict"}),
    "numpy": frozenset({"dtype", "ndarray", "bool_", "float16", "float32", "float64", "int8", "int16", "int32"})
    | frozenset({"int64", "uint8", "uint16", "uint32", "uint64"}),
    "numpy.dtypes": frozenset({"Float32DType", "Float64DType", "Int64DType", "Int32DType", "UInt8DType", "BoolDType"}),
    "numpy._core.numeric": frozenset({"_frombuffer"}),
    "numpy.core.numeric": frozenset({"_frombuffer"}),
    "numpy._core.multiarray": frozenset({"_reconstruct", "scalar"}),
    "numpy.core.multiarray": frozenset({"_reconstruct", "scalar"}),
    "numpy.random._pickle": frozenset({"__bit_generator_ctor", "__generator_ctor", "__randomstate_ctor"}),
    "numpy.random._pcg64": frozenset({"PCG64", "PCG64DXSM"}),
    "numpy.random._mt19937": frozenset({"MT19937"}),
    "numpy.random._philox": frozenset({"Philox"}),
    "numpy.random._sfc64": frozenset({"SFC64"}),
    "numpy.random.bit_generator": frozenset({"SeedSequence", "__pyx_unpickle_SeedSequence"}),
    "gymnasium.spaces.box": frozenset({"Box"}),
    "gymnasium.spaces.discrete": frozenset({"Discrete"}),
    "gymnasium.spaces.multi_discrete": frozenset({"MultiDiscrete"}),
    "gymnasium.spaces.multi_binary": frozenset({"MultiBinary"}),
    "gymnasium.spaces.dict": frozenset({"Dict"}),
    "gymnasium.spaces.tuple": frozenset({"Tuple"}),
    "stable_baselines3.common.utils": frozenset({"ConstantSchedule", "FloatSchedule", "LinearSchedule"}),
    "stable_baselines3.common.type_aliases": frozenset({"TrainFreq", "TrainFrequencyUnit"}),
    "stable_baselines3.common.running_mean_std": frozenset({"RunningMeanStd"}),
    "stable_baselines3.common.vec_env.vec_normalize": frozenset({"VecNormalize"}),
    "stable_baselines3.common.buffers": frozenset({"ReplayBuffer", "DictReplayBuffer", "NStepReplayBuffer"}),
    "stable_baselines3.her.her_replay_buffer": frozenset({"HerReplayBuffer"}),
    "stable_baselines3.her.goal_selection_strategy": frozenset({"GoalSelectionStrategy"}),
    "stable_baselines3.common.noise": frozenset(
        {"NormalActionNoise", "OrnsteinUhlenbeckActionNoise", "VectorizedActionNoise"}
    ),
    "torch.nn.modules.activation": frozenset({"ReLU", "Tanh", "ELU", "LeakyReLU", "SiLU", "GELU", "Sigmoid", "Softplus"}),
    "torch.nn.modules.linear": frozenset({"Identity"}),
    "torch.optim.adam": frozenset({"Adam"}),
    "torch.optim.adamw": frozenset({"AdamW"}),
    "torch.optim.sgd": frozenset({"SGD"}),
    "torch.optim.rmsprop": frozenset({"RMSprop"}),
}
#: Packages all of whose classes (not functions) a safe load may build.
ALLOWED_PACKAGES = ("sb3_adc", "sb3_adc_envs")
#: The package of SB3, whose policy, buffer and noise classes (subclasses of ``BasePolicy``, ``BaseBuffer`` and
#: ``ActionNoise``) a safe load may build.
SB3_PACKAGE = "stable_baselines3"
#: Packages whose policy, buffer and noise classes a safe load may build: SB3's and SB3-Contrib's (``tqc`` and
#: ``crossq`` are SB3-Contrib's algorithms).
SB3_PACKAGES = (SB3_PACKAGE, "sb3_contrib")


def _merge(*lists: Mapping[str, frozenset[str]]) -> dict[str, frozenset[str]]:
    merged: dict[str, frozenset[str]] = {}
    for names in lists:
        for module, members in names.items():
            merged[module] = merged.get(module, frozenset()) | members
    return merged


#: numpy's arrays, scalars, dtypes and random generators, as every pickle of a run holds them (numpy 2's module
#: names and numpy 1's).
NUMPY_GLOBALS: dict[str, frozenset[str]] = {
    module: names for module, names in ALLOWED.items() if module == "numpy" or module.startswith("numpy.")
}
#: Gymnasium's spaces (a replay buffer and ``VecNormalize`` keep the environment's).
SPACE_GLOBALS: dict[str, frozenset[str]] = {
    module: names for module, names in ALLOWED.items() if module.startswith("gymnasium.spaces.")
}
#: Harmless constructors of Python's own types that a pickle may name.
BUILTIN_GLOBALS: dict[str, frozenset[str]] = {module: ALLOWED[module] for module in ("builtins", "collections")}
#: The globals of a replay buffer saved by SB3's ``save_replay_buffer`` (a checkpoint's
#: ``rl_model_replay_buffer_{t}_steps.pkl``, the RL Zoo's ``replay_buffer.pkl``): SB3's buffer classes (HER's
#: with its goal-selection enum: SB3 drops its environment before pickling), numpy, the spaces and the buffer's
#: ``torch.device``.
REPLAY_BUFFER_GLOBALS: dict[str, frozenset[str]] = _merge(
    NUMPY_GLOBALS,
    SPACE_GLOBALS,
    BUILTIN_GLOBALS,
    {"torch": frozenset({"device"})},
    {
        module: ALLOWED[module]
        for module in ALLOWED
        if module.startswith(("stable_baselines3.common.buffers", "stable_baselines3.her."))
    },
)
#: The globals of ``VecNormalize`` statistics (a checkpoint's ``rl_model_vecnormalize_{t}_steps.pkl``, a run's
#: ``vecnormalize.pkl``): ``VecNormalize`` without its environments, its ``RunningMeanStd``, numpy and the spaces.
VEC_NORMALIZE_GLOBALS: dict[str, frozenset[str]] = _merge(
    NUMPY_GLOBALS,
    SPACE_GLOBALS,
    BUILTIN_GLOBALS,
    {module: ALLOWED[module] for module in ALLOWED if module.endswith((".running_mean_std", ".vec_normalize"))},
)
#: The tensors of a pickle (PyTorch's random states in a continuation): rebuilt from their storage, which pickle
#: keeps as ``torch.save`` bytes read back with ``torch.load(weights_only=True)`` (see :data:`_SUBSTITUTES`).
TENSOR_GLOBALS: dict[str, frozenset[str]] = {
    "torch._utils": frozenset({"_rebuild_tensor_v2"}),
    "torch.storage": frozenset({"_load_from_bytes"}),
}
#: The globals of a continuation (a checkpoint's ``rl_model_continuation_{t}_steps.pkl``,
#: :class:`~sb3_adc.experiment.continuation.Continuation`): its own classes, numpy's arrays, scalars and generator
#: states, PyTorch's random states (tensors) and the environments' infos (dicts of numbers and arrays).
CONTINUATION_GLOBALS: dict[str, frozenset[str]] = _merge(
    BUILTIN_GLOBALS,
    NUMPY_GLOBALS,
    TENSOR_GLOBALS,
    {"sb3_adc.experiment.continuation": frozenset({"Continuation", "EpisodeRecord", "PendingStep"})},
)


def _storage_from_bytes(data: bytes) -> Any:
    """PyTorch's ``torch.storage._load_from_bytes`` (``torch.load(weights_only=False)``), restricted to weights."""
    import torch as th

    return th.load(io.BytesIO(data), weights_only=True)


#: Globals built by a function of our own instead of the one the pickle names: the same result, without the
#: unrestricted unpickling inside.
_SUBSTITUTES: dict[tuple[str, str], Callable[..., Any]] = {("torch.storage", "_load_from_bytes"): _storage_from_bytes}


class UnsafeModelFileError(pickle.UnpicklingError, ValueError):
    """
    A model file that a safe load refuses: an entry would run or import code outside :data:`ALLOWED` (a
    ``ValueError``, as the other errors of a model file that cannot be loaded are). Also raised for a pickle of a run
    folder that needs a global outside its allow-list (:func:`restricted_load`).
    """


class DamagedEntryError(UnsafeModelFileError):
    """An entry of a model zip's ``data`` that does not unpickle at all (a damaged file rather than a refused one)."""


def _allowed(module: str, name: str, value: Any) -> bool:
    if name in ALLOWED.get(module, frozenset()):
        return True
    if any(module.startswith(f"{package}.") for package in SB3_PACKAGES) and isinstance(value, type):
        from stable_baselines3.common.buffers import BaseBuffer
        from stable_baselines3.common.noise import ActionNoise
        from stable_baselines3.common.policies import BasePolicy

        return issubclass(value, BasePolicy | BaseBuffer | ActionNoise)
    in_package = any(module == package or module.startswith(f"{package}.") for package in ALLOWED_PACKAGES)
    return in_package and isinstance(value, type) and value.__module__ == module


class _RestrictedUnpickler(pickle.Unpickler):
    """
    An unpickler that builds only allow-listed globals: ``allowed`` (``module -> names``, nothing else), or by
    default those of a model zip (:data:`ALLOWED`, and the classes :func:`_allowed` accepts).
    """

    def __init__(self, file: Any, allowed: Mapping[str, frozenset[str]] | None = None):
        super().__init__(file)
        self._globals = allowed

    def find_class(self, module: str, name: str) -> Any:
        if self._globals is not None:
            if name not in self._globals.get(module, frozenset()):
                raise UnsafeModelFileError(f"{module}.{name}")
            substitute = _SUBSTITUTES.get((module, name))
            return substitute if substitute is not None else super().find_class(module, name)
        if module in ALLOWED or module.split(".")[0] in (*ALLOWED_PACKAGES, *SB3_PACKAGES):
            # Importing an allow-listed module runs only the installed code of numpy, gymnasium, SB3, torch or
            # this package; the name is then checked against the list.
            value = super().find_class(module, name)
            if _allowed(module, name, value):
                return value
        raise UnsafeModelFileError(f"{module}.{name}")


def _entry(key: str, item: dict[str, Any], name: str) -> Any:
    try:
        raw = base64.b64decode(str(item[":serialized:"]).encode(), validate=True)
        return _RestrictedUnpickler(io.BytesIO(raw)).load()
    except UnsafeModelFileError as error:
        raise UnsafeModelFileError(
            f"Safe loading refuses {name}: its entry `{key}` needs `{error}`, which is not among the classes a safe "
            "load builds (numpy, Gymnasium spaces, SB3 schedules, buffers and noises, torch activations and "
            f"optimizers, sb3_adc classes). Pass `custom_objects={{'{key}': ...}}` to supply it, or load with "
            "`safe=False` only if you trust whoever made the file: that unpickles it, which can run any code."
        ) from None
    except (binascii.Error, pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError, IndexError) as error:
        reason = f"{type(error).__name__}: {error}"
        raise DamagedEntryError(f"{name}: the entry `{key}` of its `data` is damaged ({reason})") from None


def safe_objects(path: str | pathlib.Path | io.BufferedIOBase, custom_objects: dict[str, Any] | None = None) -> dict[str, Any]:
    """
    The ``custom_objects`` that load the model zip at ``path`` without unpickling anything it holds: every
    cloudpickled entry of its ``data``, built by an unpickler restricted to :data:`ALLOWED`, then the caller's
    ``custom_objects`` (which win, and are not read from the file).

    :param path: The model zip (or a file-like, rewound afterwards)
    :param custom_objects: The caller's objects, used instead of the file's entries of the same names
    :raises UnsafeModelFileError: naming the entry and the class or function it would need
    :raises DamagedEntryError: for an entry that does not unpickle (an ``UnsafeModelFileError`` too)
    :raises zipfile.BadZipFile: for a file that is not a zip
    :raises KeyError: for a zip without a ``data`` entry
    """
    given = dict(custom_objects or {})
    name = str(path) if isinstance(path, str | pathlib.Path) else repr(path)
    position = path.tell() if isinstance(path, io.BufferedIOBase) else None
    if isinstance(path, str | pathlib.Path) and not str(path).endswith(".zip") and not pathlib.Path(path).exists():
        path = f"{path}.zip"  # SB3's convention: `load("model")` reads model.zip
    with zipfile.ZipFile(path) as archive:
        data = json.loads(archive.read("data").decode())
    if position is not None:
        assert isinstance(path, io.BufferedIOBase)
        path.seek(position)
    if not isinstance(data, dict):
        raise UnsafeModelFileError(f"{name}: its `data` entry is not a JSON object")
    objects = {
        key: _entry(key, item, name)
        for key, item in data.items()
        if key not in given and isinstance(item, dict) and ":serialized:" in item
    }
    return {**objects, **given}


def load_objects(path: str, trust: bool = False) -> dict[str, Any] | None:
    """
    The ``custom_objects`` for SB3's ``load`` (or ``load_from_zip_file``) of the model zip at ``path``:
    :func:`safe_objects`, or ``None`` when the file is trusted (SB3 unpickles it) or too damaged to read its ``data``
    (not a zip, no ``data``, not JSON): SB3's load then fails on that same damage before it unpickles anything, with
    the error every load gives.

    :param path: The model zip
    :param trust: Unpickle the file as SB3 does (which runs any code it holds)
    :raises UnsafeModelFileError: for an entry outside the safe load's allow-list (unless ``trust``)
    """
    if trust:
        return None
    try:
        return safe_objects(path)
    except UnsafeModelFileError:
        raise
    except (OSError, zipfile.BadZipFile, KeyError, ValueError):
        return None


def restricted_load(path: str, allowed: Mapping[str, frozenset[str]], what: str) -> Any:
    """
    Unpickle the file at ``path``, building only the globals of ``allowed``: a file that needs any other is refused
    before anything of it is built, so it runs no code.

    :param path: The pickle
    :param allowed: ``module -> names`` it may build
    :param what: What the file should hold, for the message (e.g. ``"a replay buffer"``)
    :raises UnsafeModelFileError: for a file that needs another global, naming it
    :raises Exception: whatever unpickling a damaged (truncated, corrupted) file raises, as ``pickle.load`` does
    """
    with open(path, "rb") as stream:
        try:
            return _RestrictedUnpickler(stream, allowed).load()
        except DamagedEntryError:
            raise
        except UnsafeModelFileError as error:
            raise UnsafeModelFileError(
                f"{path} is not {what} as sb3-adc writes it: unpickling it needs `{error}`, which such a file never "
                "holds, so it was refused and nothing of it was run (a file planted or replaced by someone else, or "
                "written by other code). Unpickle it only if you trust whoever wrote it: it could run any code."
            ) from None


def load_vec_normalize(path: str | VecNormalize, venv: VecEnv) -> VecNormalize:
    """
    SB3's ``VecNormalize.load`` without running code from the file: the statistics pickle is read with the restricted
    unpickler (a run's ``vecnormalize.pkl`` holds a ``VecNormalize``, its ``RunningMeanStd`` and numpy arrays:
    :data:`VEC_NORMALIZE_GLOBALS`).

    :param path: The saved statistics, or statistics read already (e.g. by a checkpoint's check), which are used
    :param venv: The environments to wrap
    :raises UnsafeModelFileError: for a file that needs anything else, or holds no ``VecNormalize``
    """
    from stable_baselines3.common.vec_env import VecNormalize

    if isinstance(path, VecNormalize):
        normalize = path
    else:
        normalize = restricted_load(path, VEC_NORMALIZE_GLOBALS, "VecNormalize statistics")
    if not isinstance(normalize, VecNormalize):
        raise UnsafeModelFileError(f"{path} holds a {type(normalize).__name__}, not VecNormalize statistics")
    normalize.set_venv(venv)
    return normalize
