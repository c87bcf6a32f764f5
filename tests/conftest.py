"""Shared test configuration: one torch thread per test process keeps tiny-network tests fast and stable."""

import os
from collections.abc import Iterator

import pytest
import torch as th

th.set_num_threads(1)


@pytest.fixture(autouse=True, scope="session")
def sb3_log_folder(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """
    SB3's ``configure_logger`` makes a new ``SB3-<date>`` folder in the system's temporary directory for every
    model without a log folder; ``SB3_LOGDIR`` sends them all to one folder of pytest's own (rotated) ones.
    """
    previous = os.environ.get("SB3_LOGDIR")
    os.environ["SB3_LOGDIR"] = str(tmp_path_factory.mktemp("sb3_logs"))
    yield
    if previous is None:
        del os.environ["SB3_LOGDIR"]
    else:
        os.environ["SB3_LOGDIR"] = previous
