"""Atomic writes create their temporary file exclusively: a link planted at its name is not written through."""

import os

import numpy as np
import pytest

from sb3_adc.common.atomic import atomic_path, temporary_name, write_atomically

pytestmark = pytest.mark.skipif(not hasattr(os, "symlink") or os.name == "nt", reason="needs POSIX symlinks")


@pytest.fixture
def outside(tmp_path_factory):
    """A file outside the run folder that a planted link points to."""
    path = tmp_path_factory.mktemp("outside") / "precious.txt"
    path.write_text("precious\n")
    return path


def test_checkpoint_write_does_not_follow_a_planted_link(tmp_path, outside):
    from stable_baselines3 import DDPG

    model = DDPG("MlpPolicy", "Pendulum-v1", policy_kwargs={"net_arch": [4]}, buffer_size=10, device="cpu")
    target = tmp_path / "rl_model_100_steps.zip"
    os.symlink(outside, tmp_path / "rl_model_100_steps.partial.zip")
    with atomic_path(target) as temporary:
        model.save(temporary)
    assert outside.read_text() == "precious\n"
    assert not os.path.islink(target)
    assert DDPG.load(target, device="cpu").policy is not None
    assert sorted(os.listdir(tmp_path)) == ["rl_model_100_steps.zip"]


def test_stream_write_does_not_follow_a_planted_link(tmp_path, outside):
    target = tmp_path / "evaluations.npz"
    os.symlink(outside, temporary_name(target))
    write_atomically(target, lambda stream: np.savez(stream, timesteps=np.arange(3)), binary=True)
    assert outside.read_text() == "precious\n"
    assert list(np.load(target)["timesteps"]) == [0, 1, 2]
    assert sorted(os.listdir(tmp_path)) == ["evaluations.npz"]


def test_a_dangling_planted_link_creates_nothing_outside(tmp_path, tmp_path_factory):
    missing = tmp_path_factory.mktemp("outside") / "created.txt"
    target = tmp_path / "config.yml"
    os.symlink(missing, temporary_name(target))
    write_atomically(target, lambda stream: stream.write("a: 1\n"))
    assert not missing.exists()
    assert target.read_text() == "a: 1\n"


def test_written_files_keep_the_umask_permissions(tmp_path):
    previous = os.umask(0o022)
    try:
        write_atomically(tmp_path / "table.csv", lambda stream: stream.write("x\n"))
    finally:
        os.umask(previous)
    assert (tmp_path / "table.csv").stat().st_mode & 0o777 == 0o644
