"""
A resume reads the run folder's files without running code from them: the checkpoint's model zip with the safe load,
its replay buffer, ``VecNormalize`` statistics and continuation with unpicklers that build only what sb3-adc writes in
each. A checkpoint's manifest finds a file changed after it was written before anything is unpickled (set aside as
damage); a hostile file planted with a manifest that lists it is refused (the run folder left as it was), not
executed nor taken for damage; ``trust_model_file`` unpickles as SB3 does. The check that chooses the checkpoint
unpickles each file once, and the resume uses what it read.
"""

from __future__ import annotations

import base64
import io
import json
import os
import pickle
import shutil
import zipfile
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cloudpickle
import pytest
import torch as th

import sb3_adc.common.safe_load as safe_load
import sb3_adc.experiment.restore as restore
from sb3_adc.common.safe_load import CONTINUATION_GLOBALS, UnsafeModelFileError
from sb3_adc.experiment import TrainSettings, resume, train
from sb3_adc.experiment.continuation import Continuation
from sb3_adc.experiment.layout import RunLayout
from sb3_adc.experiment.manifest import write_manifest
from sb3_adc.experiment.restore import DamagedCheckpoint, checkpoint_damage, read_checkpoint

MARKER = "SB3_ADC_RUN_FILE_PAYLOAD_MARKER"


class _RunsCode:
    """Unpickling this runs Python code (it sets an environment variable): a stand-in for any payload."""

    def __reduce__(self) -> tuple[object, tuple[str]]:
        return (exec, (f"import os; os.environ[{MARKER!r}] = 'ran'",))


class _StorageRunsCode:
    """A pickle that asks ``torch.storage._load_from_bytes`` (``torch.load(weights_only=False)``) to read a payload:
    the way a tensor's storage is pickled, so a continuation's allow-list must name it."""

    def __reduce__(self) -> tuple[object, tuple[bytes]]:
        import torch.storage

        return (torch.storage._load_from_bytes, (pickle.dumps(_RunsCode()),))


@pytest.fixture(autouse=True)
def _no_marker(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(MARKER, raising=False)


@pytest.fixture(scope="module")
def crashed(tmp_path_factory: pytest.TempPathFactory, tiny_settings: Callable[..., TrainSettings]) -> Path:
    """A run left as a crash after its checkpoint at timestep 200 leaves it (checkpoints at 100 and 200)."""
    folder = tmp_path_factory.mktemp("crashed")
    # With VecNormalize: a checkpoint holds all four kinds of file.
    run_dir = train(tiny_settings(folder, "adc-normalized", keep_checkpoints=5)).run_dir
    layout = RunLayout(run_dir, "Pendulum-v1")
    for checkpoint in layout.checkpoints():
        if checkpoint.timesteps > 200:
            checkpoint.remove()
    for path in (layout.final_model, layout.final_evaluation, layout.vecnormalize):
        os.remove(path)
    return Path(run_dir)


@pytest.fixture
def run_dir(crashed: Path, tmp_path: Path) -> Path:
    copy = tmp_path / "run"
    shutil.copytree(crashed, copy)
    return copy


def _plant_in_zip(path: Path, key: str) -> None:
    with zipfile.ZipFile(path) as archive:
        entries = {name: archive.read(name) for name in archive.namelist()}
    data = json.loads(entries["data"])
    data[key] = {":type:": "<class 'object'>", ":serialized:": base64.b64encode(cloudpickle.dumps(_RunsCode())).decode()}
    entries["data"] = json.dumps(data).encode()
    with zipfile.ZipFile(path, "w") as archive:
        for name, content in entries.items():
            archive.writestr(name, content)


def _resign(run_dir: Path) -> None:
    """Rewrite the manifest of the checkpoint at 200 for its files as they are now, as whoever can write the run
    folder can: the manifest is an integrity check, not a signature, and a planted file must still be refused."""
    write_manifest(RunLayout(str(run_dir), "Pendulum-v1").checkpoint(200))


def _listing(folder: Path) -> dict[str, bytes]:
    return {path.name: path.read_bytes() for path in folder.iterdir() if path.is_file() and path.name != ".lock"}


@pytest.mark.parametrize(
    "planted",
    [
        "rl_model_replay_buffer_200_steps.pkl",
        "rl_model_vecnormalize_200_steps.pkl",
        "rl_model_continuation_200_steps.pkl",
        "rl_model_200_steps.zip",
    ],
)
def test_a_hostile_file_in_a_checkpoint_is_refused_not_run(run_dir, planted):
    if planted.endswith(".zip"):
        _plant_in_zip(run_dir / planted, "action_noise")
    else:
        (run_dir / planted).write_bytes(pickle.dumps(_RunsCode()))
    _resign(run_dir)
    before = _listing(run_dir)
    with pytest.raises(UnsafeModelFileError, match=r"builtins\.exec") as error:
        resume(str(run_dir))
    assert planted in str(error.value)
    assert MARKER not in os.environ
    # Refused, not taken for damage: nothing renamed *.damaged, nothing resumed from an older checkpoint.
    assert _listing(run_dir) == before
    with pytest.raises(UnsafeModelFileError):
        read_checkpoint(RunLayout(str(run_dir), "Pendulum-v1").checkpoint(200))
    assert MARKER not in os.environ


@pytest.mark.parametrize(
    ("listed", "damage"), [(True, "does not match its manifest (size differs)"), (False, "is not in its manifest")]
)
def test_a_file_its_manifest_does_not_list_is_damage_found_without_unpickling(run_dir, monkeypatch, capsys, listed, damage):
    planted = "rl_model_continuation_200_steps.pkl"
    if not listed:
        (run_dir / planted).unlink()
        _resign(run_dir)
    (run_dir / planted).write_bytes(pickle.dumps(_RunsCode()))
    read: list[str] = []
    real_restricted = safe_load.restricted_load

    def recorded(path: str, *args: Any) -> Any:
        read.append(os.path.basename(path))
        return real_restricted(path, *args)

    monkeypatch.setattr(restore, "restricted_load", recorded)
    assert checkpoint_damage(RunLayout(str(run_dir), "Pendulum-v1").checkpoint(200)) == f"{planted} {damage}"
    result = resume(str(run_dir))
    # Set aside as damaged before anything of it was unpickled; the run went on from the checkpoint before it.
    assert planted not in read
    assert MARKER not in os.environ
    assert result.resumed_from == 100
    assert (run_dir / (planted + ".damaged")).is_file()
    assert f"The checkpoint at timestep 200 is damaged ({planted} {damage})" in capsys.readouterr().out


def test_the_cli_refuses_a_planted_file_with_exit_2(run_dir, capsys):
    from sb3_adc.cli import main

    (run_dir / "rl_model_continuation_200_steps.pkl").write_bytes(pickle.dumps(_RunsCode()))
    _resign(run_dir)
    assert main(["train", "--resume", str(run_dir), "--no-progress-bar"]) == 2
    err = capsys.readouterr().err
    assert "rl_model_continuation_200_steps.pkl" in err
    assert "--trust-model-file" in err
    assert MARKER not in os.environ


def test_trust_model_file_unpickles_the_run_folder_as_sb3_does(run_dir, capsys):
    (run_dir / "rl_model_continuation_200_steps.pkl").write_bytes(pickle.dumps(_RunsCode()))
    _resign(run_dir)
    result = resume(str(run_dir), trust_model_file=True)
    assert os.environ.get(MARKER) == "ran"
    # The payload's result is no continuation: the run went on from a new random stream.
    assert result.resumed_from == 200
    assert "new random stream" in capsys.readouterr().out


@pytest.mark.filterwarnings("ignore:Detected pickle protocol")
def test_a_tensor_storage_cannot_smuggle_an_unrestricted_load(run_dir):
    # PyTorch pickles a tensor's storage as bytes for `torch.load(weights_only=False)`; the continuation's
    # unpickler reads them with `weights_only=True`, which refuses the payload: a damaged file, nothing run.
    assert ("torch.storage", "_load_from_bytes") in {
        (module, name) for module, names in CONTINUATION_GLOBALS.items() for name in names
    }
    path = run_dir / "rl_model_continuation_200_steps.pkl"
    path.write_bytes(pickle.dumps(_StorageRunsCode()))
    _resign(run_dir)
    with pytest.raises(DamagedCheckpoint, match=r"rl_model_continuation_200_steps\.pkl does not unpickle"):
        read_checkpoint(RunLayout(str(run_dir), "Pendulum-v1").checkpoint(200))
    assert MARKER not in os.environ


def test_own_checkpoints_read_completely_with_the_allow_lists(run_dir):
    contents = read_checkpoint(RunLayout(str(run_dir), "Pendulum-v1").checkpoint(200))
    assert contents.model_objects is not None
    assert "observation_space" in contents.model_objects
    assert contents.replay_buffer is not None
    assert contents.replay_buffer.size() > 100
    assert contents.vecnormalize is not None
    assert contents.vecnormalize.ret_rms.count > 1
    assert isinstance(contents.continuation, Continuation)
    assert contents.continuation.timesteps == 200
    assert isinstance(contents.continuation.random_states["torch"], th.Tensor)
    # The same objects as SB3's unrestricted unpickling gives.
    unrestricted = pickle.loads((run_dir / "rl_model_continuation_200_steps.pkl").read_bytes())
    assert th.equal(unrestricted.random_states["torch"], contents.continuation.random_states["torch"])


def test_a_resume_reads_each_file_of_its_checkpoint_once(run_dir, monkeypatch, capsys):
    reads: Counter[str] = Counter()
    real_restricted, real_safe_objects = safe_load.restricted_load, safe_load.safe_objects

    def counted_restricted(path: str, *args: Any) -> Any:
        reads[os.path.basename(path)] += 1
        return real_restricted(path, *args)

    def counted_safe_objects(path: Any, *args: Any) -> Any:
        reads[os.path.basename(str(path))] += 1
        return real_safe_objects(path, *args)

    def unrestricted(*args: Any, **kwargs: Any) -> Any:
        raise AssertionError("a run file was unpickled without restriction")

    for module in (safe_load, restore):
        monkeypatch.setattr(module, "restricted_load", counted_restricted)
    monkeypatch.setattr(restore, "safe_objects", counted_safe_objects)
    monkeypatch.setattr(restore, "load_from_pkl", unrestricted)
    monkeypatch.setattr("stable_baselines3.common.off_policy_algorithm.load_from_pkl", unrestricted)
    result = resume(str(run_dir))
    assert result.resumed_from == 200
    assert "new random stream" not in capsys.readouterr().out
    assert {name: count for name, count in reads.items() if "_200_" in name} == {
        "rl_model_200_steps.zip": 1,
        "rl_model_replay_buffer_200_steps.pkl": 1,
        "rl_model_vecnormalize_200_steps.pkl": 1,
        "rl_model_continuation_200_steps.pkl": 1,
    }


def test_the_allow_lists_name_no_code_runners() -> None:
    lists = {
        "replay buffer": safe_load.REPLAY_BUFFER_GLOBALS,
        "vecnormalize": safe_load.VEC_NORMALIZE_GLOBALS,
        "continuation": CONTINUATION_GLOBALS,
    }
    dangerous = {"eval", "exec", "getattr", "setattr", "__import__", "compile", "open", "apply", "system"}
    for kind, allowed in lists.items():
        for module, names in allowed.items():
            assert not module.startswith(("os", "subprocess", "sys", "importlib", "pickle", "shutil")), (kind, module)
            assert not names & dangerous, (kind, module)
    # A plain pickle of a builtin that runs code is refused by each.
    for allowed in lists.values():
        with pytest.raises(UnsafeModelFileError):
            safe_load._RestrictedUnpickler(io.BytesIO(pickle.dumps(_RunsCode())), allowed).load()
    assert MARKER not in os.environ
