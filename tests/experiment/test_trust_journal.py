"""A tuning journal whose last line was torn by a crash mid-write is repaired when the study is opened again."""

import optuna
import pytest

from sb3_adc.experiment.tuning import tune
from sb3_adc.experiment.tuning_storage import repair_journal


def test_study_resumes_after_a_torn_last_line(tiny_study):
    settings = tiny_study(seeds=(0,))
    tune(settings)
    path = settings.storage_url()
    with open(path, "rb") as stream:
        text = stream.read()
    assert text.endswith(b"\n")
    torn = text[:-5]  # a crash mid-write: the last record without its end and newline
    with open(path, "wb") as stream:
        stream.write(torn)
    settings.n_trials = 3
    with pytest.warns(UserWarning, match="cut short"):
        result = tune(settings)
    assert result.n_finished == 3
    with open(f"{path}.torn-0", "rb") as stream:
        assert stream.read() == torn
    # The journal reads back whole, and a further run goes on from it.
    storage = optuna.storages.JournalStorage(optuna.storages.journal.JournalFileBackend(path))
    study = optuna.load_study(study_name=settings.name, storage=storage)
    assert len([t for t in study.trials if t.state.is_finished()]) == 3


def test_repair_leaves_whole_journals_alone(tmp_path):
    path = tmp_path / "study.log"
    assert repair_journal(str(path)) is None
    path.write_bytes(b'{"a":1}\n')
    assert repair_journal(str(path)) is None
    assert path.read_bytes() == b'{"a":1}\n'
    path.write_bytes(b'{"a":1}\n{"b"')
    with pytest.warns(UserWarning, match="study.log.torn-0"):
        assert repair_journal(str(path)) == f"{path}.torn-0"
    assert path.read_bytes() == b'{"a":1}\n'
    path.write_bytes(b'{"a"')
    with pytest.warns(UserWarning, match="study.log.torn-1"):
        assert repair_journal(str(path)) == f"{path}.torn-1"
    assert path.read_bytes() == b""
