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


class _RunsCode:
    """Unpickling this runs Python code (it sets the environment variable ``marker``): a stand-in for any payload."""

    def __init__(self, marker: str):
        self.marker = marker

    def __reduce__(self) -> tuple[object, tuple[str]]:
        return (exec, (f"import os; os.environ[{self.marker!r}] = 'ran'",))


class HostilePickles:
    """
    Hostile files for the tests of safe loading: :attr:`payload` sets the environment variable :attr:`marker` when it
    is unpickled, and :meth:`zip_with_entry` plants a value in a copy of a model zip.
    """

    marker = "SB3_ADC_TEST_PAYLOAD_MARKER"

    def __init__(self) -> None:
        self.payload = _RunsCode(self.marker)

    @staticmethod
    def zip_with_serialized(path: os.PathLike[str], key: str, serialized: str, target: os.PathLike[str]) -> os.PathLike[str]:
        """A copy at ``target`` of the zip at ``path`` whose ``data`` entry ``key`` has the ``:serialized:`` text given."""
        import json
        import zipfile

        with zipfile.ZipFile(path) as archive:
            entries = {name: archive.read(name) for name in archive.namelist()}
        data = json.loads(entries["data"])
        data[key] = {":type:": "<class 'object'>", ":serialized:": serialized}
        entries["data"] = json.dumps(data).encode()
        with zipfile.ZipFile(target, "w") as archive:
            for name, content in entries.items():
                archive.writestr(name, content)
        return target

    def zip_with_entry(self, path: os.PathLike[str], key: str, value: object, target: os.PathLike[str]) -> os.PathLike[str]:
        """A copy at ``target`` of the zip at ``path`` whose ``data`` entry ``key`` is ``value``, cloudpickled as SB3 does."""
        import base64

        import cloudpickle

        return self.zip_with_serialized(path, key, base64.b64encode(cloudpickle.dumps(value)).decode(), target)


@pytest.fixture
def hostile(monkeypatch: pytest.MonkeyPatch) -> HostilePickles:
    """Hostile files that run code when unpickled (:class:`HostilePickles`), their marker unset during the test."""
    monkeypatch.setenv(HostilePickles.marker, "unset")  # recorded, so that it is removed again after the test
    monkeypatch.delenv(HostilePickles.marker)
    return HostilePickles()
