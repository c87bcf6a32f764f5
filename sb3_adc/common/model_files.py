"""
Loading model files: errors that name the file and say what is wrong, catchable where SB3's errors are.

SB3's ``load`` and ``set_parameters`` let the error of whichever step failed through (a ``KeyError`` of a
missing archive entry, an ``EOFError`` or ``RuntimeError`` of a truncated one, a raw torch size mismatch, a
``FileNotFoundError`` that names ``x.zip.zip`` for a missing ``x.zip``). Our algorithms raise a
:class:`ModelFileError` instead: a ``ValueError`` whose message names the file, raised as a subclass that is
also the type SB3 raises in the same situation, so that code written against SB3 keeps working.
"""

from __future__ import annotations

import contextlib
import errno
import io
import os
import pathlib
import pickle
import warnings
import zipfile
import zlib
from collections.abc import Iterator, Mapping
from typing import Any, TypeAlias, TypeVar

import torch as th
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.save_util import load_from_zip_file, recursive_getattr
from stable_baselines3.common.type_aliases import GymEnv, TensorDict

from sb3_adc.common.safe_load import UnsafeModelFileError, safe_objects

#: A model file: its path, or a file-like.
ModelPath: TypeAlias = str | pathlib.Path | io.BufferedIOBase
#: What :meth:`CheckedModelFiles._load_arguments` returns: the ``custom_objects`` and keyword arguments for SB3's ``load``.
LoadArguments: TypeAlias = tuple[dict[str, Any] | None, dict[str, Any]]

#: What SB3 (from 2.8) warns in ``_setup_model`` when an off-policy model with ``n_steps > 1`` is given its
#: ``replay_buffer_class``. A loaded model always is: the file holds the ``NStepReplayBuffer`` and the ``n_steps``
#: and ``gamma`` SB3 put into ``replay_buffer_kwargs`` when it built the model, so the loaded model does learn
#: from n-step returns and the warning that ``n_steps`` "is ignored" is wrong there. A subclass of the buffer
#: (another name) is still warned about.
LOADED_N_STEP_WARNING = r"`n_steps=\d+` is ignored because a custom `replay_buffer_class` \(`NStepReplayBuffer`\)"


@contextlib.contextmanager
def loading_model() -> Iterator[None]:
    """
    Load a model file inside this: SB3's warning that a loaded n-step model's ``n_steps`` is ignored, which it is
    not (:data:`LOADED_N_STEP_WARNING`), stays silent; every other warning is shown.
    """
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=LOADED_N_STEP_WARNING, category=UserWarning)
        yield


#: The errors SB3's loader lets through from a damaged or foreign archive: the zip reader's, the unpickler's and
#: torch's errors on a truncated entry, a missing entry, and SB3's own assertions on the archive's content.
_DAMAGED_FILE_ERRORS = (
    zipfile.BadZipFile,
    zlib.error,
    EOFError,
    pickle.UnpicklingError,
    KeyError,
    RuntimeError,
    AssertionError,
)


class ModelFileError(ValueError):
    """
    A model file (or a dictionary of parameters) that cannot be loaded into the model asked for.

    It is raised as a subclass that is also the type of the error SB3 raises in the same situation (for
    instance ``KeyError``, ``EOFError`` or ``RuntimeError``): ``except ValueError`` and SB3's ``except`` clauses
    both catch it. ``catchable_as`` is that type (``ValueError`` when SB3 raises one too).
    """

    catchable_as: type[Exception] = ValueError

    def __str__(self) -> str:
        # KeyError quotes its message; a ModelFileError reads the same whatever type it is also.
        return str(self.args[0]) if self.args else ""

    def __reduce__(self) -> tuple[Any, ...]:
        # The subclasses are made at run time: rebuild one from its message and the type it is also.
        return model_file_error, (str(self), self.catchable_as)


#: The subclasses made so far, by the type they are also (one class per type, so that ``type(a) is type(b)``).
_ERROR_CLASSES: dict[type[Exception], type[ModelFileError]] = {}


def _error_class(catchable_as: type[Exception]) -> type[ModelFileError]:
    if issubclass(ModelFileError, catchable_as):
        return ModelFileError
    if catchable_as not in _ERROR_CLASSES:
        _ERROR_CLASSES[catchable_as] = _make_error_class(catchable_as)
    return _ERROR_CLASSES[catchable_as]


def _make_error_class(catchable_as: type[Exception]) -> type[ModelFileError]:
    try:
        return type(
            "ModelFileError",
            (ModelFileError, catchable_as),
            {"__module__": __name__, "__qualname__": "ModelFileError", "catchable_as": catchable_as},
        )
    except TypeError:  # a built-in layout that cannot be combined with ValueError's
        return ModelFileError


def model_file_error(message: str, catchable_as: type[Exception] = ValueError) -> ModelFileError:
    """
    A :class:`ModelFileError` with ``message`` that is also an instance of ``catchable_as``.

    :param message: What is wrong, naming the file
    :param catchable_as: The type of the error SB3 raises in the same situation
    :return: The error, to be raised
    """
    try:
        return _error_class(catchable_as)(message)
    except TypeError:  # an exception type whose constructor needs more than a message
        return ModelFileError(message)


def _describe(path: ModelPath) -> str:
    return str(path) if isinstance(path, (str, os.PathLike)) else repr(path)


def missing_model_file(path: str | os.PathLike[str], algorithm: str) -> FileNotFoundError:
    """
    The error for a model file that does not exist, naming the path given (SB3 names the last one it tried:
    ``x.zip.zip`` for ``x.zip``).

    :param path: The path given to ``load`` or ``set_parameters``
    :param algorithm: Name of the algorithm, for the message
    :return: The error, to be raised
    """
    tried = f"{path} (nor {path}.zip)" if pathlib.Path(path).suffix != ".zip" else str(path)
    return FileNotFoundError(errno.ENOENT, f"No {algorithm} model file at {tried}")


@contextlib.contextmanager
def model_file_errors(path: ModelPath, algorithm: str) -> Iterator[None]:
    """
    Turn the errors of loading ``path`` into a :class:`ModelFileError` (or a ``FileNotFoundError``) whose
    message names the file, catchable as the error SB3 raises.

    :param path: The file given to ``load`` or ``set_parameters``
    :param algorithm: Name of the algorithm loading it, for the messages
    """
    name = _describe(path)
    try:
        yield
    except (ModelFileError, UnsafeModelFileError):
        raise
    except FileNotFoundError as error:
        if isinstance(path, (str, os.PathLike)) and not os.path.exists(path):
            raise missing_model_file(path, algorithm) from error
        raise
    except _DAMAGED_FILE_ERRORS as error:
        cause = error.__context__
        if isinstance(error, KeyError) and isinstance(cause, ValueError):
            # SB3's loader retries a failed parameter load as an old DQN file and fails on a missing key:
            # report the original failure.
            raise model_file_error(f"Cannot load the {algorithm} model {name}: {cause}", KeyError) from cause
        message = f"{name} is not a readable {algorithm} model file: {type(error).__name__}: {error}"
        raise model_file_error(message, type(error)) from error
    except (ValueError, TypeError) as error:
        raise model_file_error(f"Cannot load the {algorithm} model {name}: {error}", type(error)) from error


def check_parameter_shapes(model: BaseAlgorithm, params: Mapping[str, Any]) -> None:
    """
    Raise a :class:`ModelFileError` (also a ``RuntimeError``, as torch's size mismatch is) when a tensor of
    ``params`` (the modules' state dicts, as ``get_parameters`` returns) has another shape than the model's, for
    instance parameters saved for another number of action dimensions.

    :param model: The model the parameters are to be loaded into
    :param params: Module name to state dict
    """
    mismatches = []
    for module_name, state in params.items():
        try:
            module = recursive_getattr(model, module_name)
        except AttributeError:
            continue  # SB3 reports unknown names
        if not isinstance(module, th.nn.Module) or not isinstance(state, Mapping):
            continue
        own = module.state_dict()
        for key, tensor in state.items():
            if key in own and isinstance(tensor, th.Tensor) and tensor.shape != own[key].shape:
                mismatches.append(f"`{module_name}.{key}` {tuple(tensor.shape)} vs {tuple(own[key].shape)}")
    if mismatches:
        shown = "; ".join(mismatches[:3]) + ("; ..." if len(mismatches) > 3 else "")
        raise model_file_error(
            f"The parameters do not fit this {type(model).__name__} model ({len(mismatches)} tensor(s) of "
            f"another shape, saved vs this model: {shown}). This model has action space {model.action_space} "
            f"and observation space {model.observation_space}: parameters load only into a model built for the "
            "same spaces and network sizes.",
            RuntimeError,
        )


SelfCheckedModelFiles = TypeVar("SelfCheckedModelFiles", bound="CheckedModelFiles")


class CheckedModelFiles(BaseAlgorithm):
    """
    An SB3 algorithm whose ``load`` and ``set_parameters`` errors name the file: a :class:`ModelFileError` (a
    ``ValueError`` that is also the type SB3 raises in the same situation), a ``RuntimeError`` one for parameters of
    other shapes (where SB3 lets torch's size mismatch through), ``FileNotFoundError`` naming the path given.
    Subclasses add their own checks of the saved parameters in :meth:`_check_saved_parameters`.
    """

    def _check_saved_parameters(self, params: dict[str, Any]) -> None:
        """
        Checks of the saved parameters before their shapes are compared with this model's (none here).

        :param params: Module name to state dict
        :raises ModelFileError: for parameters this model cannot take
        """

    def set_parameters(
        self,
        load_path_or_dict: str | TensorDict,
        exact_match: bool = True,
        device: th.device | str = "auto",
    ) -> None:
        """
        Load parameters from a zip file or a dictionary of state dicts (see SB3's ``set_parameters``), after
        :meth:`_check_saved_parameters` and a check that their tensors have this model's shapes (the same spaces
        and network sizes).

        :param load_path_or_dict: Location of the saved data, or a dictionary of state dicts
        :param exact_match: If True, the given parameters must include every parameter of every module
        :param device: Device on which the code should run.
        """
        if isinstance(load_path_or_dict, dict):
            params = load_path_or_dict
        else:
            with model_file_errors(load_path_or_dict, type(self).__name__):
                _, params, _ = load_from_zip_file(load_path_or_dict, device=device, load_data=False)
        self._check_saved_parameters(params)
        check_parameter_shapes(self, params)
        super().set_parameters(params, exact_match=exact_match, device=device)

    @classmethod
    def _load_arguments(
        cls, path: ModelPath, env: GymEnv | None, custom_objects: dict[str, Any] | None, kwargs: dict[str, Any]
    ) -> LoadArguments:
        """
        The ``custom_objects`` and keyword arguments :meth:`load` passes to SB3's (unchanged here). Subclasses check
        ``env`` and read ``path`` here, inside the error handling of :meth:`load`.

        :param path: The file given to :meth:`load`
        :param env: The environment given to :meth:`load`
        :param custom_objects: The caller's ``custom_objects``
        :param kwargs: The caller's extra keyword arguments
        """
        return custom_objects, kwargs

    @classmethod
    def load(
        cls: type[SelfCheckedModelFiles],
        path: ModelPath,
        env: GymEnv | None = None,
        device: th.device | str = "auto",
        custom_objects: dict[str, Any] | None = None,
        print_system_info: bool = False,
        force_reset: bool = True,
        safe: bool = False,
        **kwargs: Any,
    ) -> SelfCheckedModelFiles:
        """
        Load a model from a zip file (see SB3's ``BaseAlgorithm.load``), with errors that name the file.

        :param path: path to the file (or a file-like) where to load the agent from
        :param env: the new environment to run the loaded model on (can be None if you only need prediction)
        :param device: Device on which the code should run.
        :param custom_objects: Dictionary of objects to replace upon loading
        :param print_system_info: Whether to print system info from the saved model
        :param force_reset: Force call to ``reset()`` before training to avoid unexpected behavior
        :param safe: Run no code from the file (:func:`~sb3_adc.common.safe_load.safe_objects`): its pickled entries
            are built from an allow-list of classes, and a file that needs anything else is refused with an
            :class:`~sb3_adc.common.safe_load.UnsafeModelFileError`. Use it for files from anyone you do not trust:
            without it, loading unpickles the file, which can run any code, as in SB3.
        :param kwargs: extra arguments to change the model when loading
        :return: new model instance with loaded parameters
        """
        with model_file_errors(path, cls.__name__), loading_model():
            if safe:
                custom_objects = safe_objects(path, custom_objects)
            custom_objects, kwargs = cls._load_arguments(path, env, custom_objects, kwargs)
            return super().load(
                path,
                env=env,
                device=device,
                custom_objects=custom_objects,
                print_system_info=print_system_info,
                force_reset=force_reset,
                **kwargs,
            )
