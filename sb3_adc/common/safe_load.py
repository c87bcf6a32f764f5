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
"""

from __future__ import annotations

import base64
import binascii
import io
import json
import pathlib
import pickle
import zipfile
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
#: Modules of SB3 whose policy, buffer and noise classes (subclasses of :data:`SB3_BASES`) a safe load may build.
SB3_PACKAGE = "stable_baselines3"


class UnsafeModelFileError(pickle.UnpicklingError, ValueError):
    """
    A model file that a safe load refuses: an entry would run or import code outside :data:`ALLOWED` (a
    ``ValueError``, as the other errors of a model file that cannot be loaded are).
    """


def _allowed(module: str, name: str, value: Any) -> bool:
    if name in ALLOWED.get(module, frozenset()):
        return True
    if module.startswith(f"{SB3_PACKAGE}.") and isinstance(value, type):
        from stable_baselines3.common.buffers import BaseBuffer
        from stable_baselines3.common.noise import ActionNoise
        from stable_baselines3.common.policies import BasePolicy

        return issubclass(value, BasePolicy | BaseBuffer | ActionNoise)
    in_package = any(module == package or module.startswith(f"{package}.") for package in ALLOWED_PACKAGES)
    return in_package and isinstance(value, type) and value.__module__ == module


class _RestrictedUnpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str) -> Any:
        if module in ALLOWED or module.split(".")[0] in (*ALLOWED_PACKAGES, SB3_PACKAGE):
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
        raise UnsafeModelFileError(
            f"{name}: the entry `{key}` of its `data` is damaged ({type(error).__name__}: {error})"
        ) from None


def safe_objects(path: str | pathlib.Path | io.BufferedIOBase, custom_objects: dict[str, Any] | None = None) -> dict[str, Any]:
    """
    The ``custom_objects`` that load the model zip at ``path`` without unpickling anything it holds: every
    cloudpickled entry of its ``data``, built by an unpickler restricted to :data:`ALLOWED`, then the caller's
    ``custom_objects`` (which win, and are not read from the file).

    :param path: The model zip (or a file-like, rewound afterwards)
    :param custom_objects: The caller's objects, used instead of the file's entries of the same names
    :raises UnsafeModelFileError: naming the entry and the class or function it would need
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


def load_vec_normalize(path: str, venv: VecEnv) -> VecNormalize:
    """
    SB3's ``VecNormalize.load`` without running code from the file: the statistics pickle is read with the restricted
    unpickler (a run's ``vecnormalize.pkl`` holds a ``VecNormalize``, its ``RunningMeanStd`` and numpy arrays).

    :param path: The saved statistics
    :param venv: The environments to wrap
    :raises UnsafeModelFileError: for a file that needs anything else
    """
    from stable_baselines3.common.vec_env import VecNormalize

    with open(path, "rb") as stream:
        try:
            normalize = _RestrictedUnpickler(stream).load()
        except UnsafeModelFileError as error:
            raise UnsafeModelFileError(
                f"{path} is not VecNormalize statistics a safe load reads: it needs `{error}`"
            ) from None
    if not isinstance(normalize, VecNormalize):
        raise UnsafeModelFileError(f"{path} holds a {type(normalize).__name__}, not VecNormalize statistics")
    normalize.set_venv(venv)
    return normalize
