"""``sb3-adc benchmark --backend ray`` on a local Ray instance: the same tables as the local backend."""

import pandas as pd
import pytest

ray = pytest.importorskip("ray")


@pytest.fixture
def local_ray():
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


def test_ray_backend_writes_the_same_tables_as_the_local_one(cli, tiny_conf, tmp_path, local_ray):
    grid = ["--algos", "adc", "--envs", "Pendulum-v1", "--seeds", "5", "-n", "200", "--conf-folder", tiny_conf]
    grid += ["--eval-freq", "100", "--eval-episodes", "1", "--final-eval-episodes", "2"]
    status, out, _ = cli("benchmark", *grid, "-f", tmp_path / "ray", "--backend", "ray")
    assert status == 0
    assert "(ray backend)" in out
    assert "adc on Pendulum-v1, seed 5 trained" in out
    assert cli("benchmark", *grid, "-f", tmp_path / "local", "--workers", "1")[0] == 0
    for table in ("evaluations.csv", "episodes.csv", "final.csv"):
        on_ray, local = pd.read_csv(tmp_path / "ray" / table), pd.read_csv(tmp_path / "local" / table)
        assert len(on_ray) > 0
        assert list(on_ray.columns) == list(local.columns)
        # Same rows and (one thread, same seeds) the same numbers, but for the seconds each episode took.
        timed = [column for column in on_ray.columns if column == "wall_time_s"]
        assert all((table[timed].to_numpy() > 0).all() for table in (on_ray, local))
        pd.testing.assert_frame_equal(on_ray.drop(columns=timed), local.drop(columns=timed), check_exact=False, rtol=1e-6)
