import json

import pytest

from xted.errors import InputError
from xted.resume import check_same_run, differences, discard_run, resume_or_record


def test_differences_name_nested_keys():
    old = {"a": 1, "b": {"c": [1, 2], "d": "x"}}
    new = {"a": 1, "b": {"c": [1, 3], "e": True}}
    assert differences(old, new) == [("b.c", [1, 2], [1, 3]), ("b.d", "x", None), ("b.e", None, True)]
    assert differences(old, old) == []


def test_record_then_resume_then_refuse(tmp_path):
    path = tmp_path / "run" / "run.json"
    resume_or_record(path, {"seed": 0, "hidden": (256, 256)})
    assert json.loads(path.read_text()) == {"seed": 0, "hidden": [256, 256]}
    resume_or_record(path, {"seed": 0, "hidden": (256, 256)})  # tuples and lists compare equal
    before = path.read_text()
    with pytest.raises(InputError, match=r"seed: 0 -> 1"):
        resume_or_record(path, {"seed": 1, "hidden": (256, 256)})
    assert path.read_text() == before  # never overwritten


def test_unreadable_record_is_named(tmp_path):
    (tmp_path / "run.json").write_text("{not json")
    with pytest.raises(InputError, match="run.json: unreadable"):
        resume_or_record(tmp_path / "run.json", {})


def test_nothing_recorded_means_a_new_run():
    check_same_run("x", None, {"anything": 1})


def test_discard_run_deletes_a_run_folder_and_refuses_any_other(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (run / "seed_0.json").write_text("{}")
    discard_run(run, ("seed_*.json",))
    assert not run.exists()
    discard_run(run, ("seed_*.json",))  # nothing there: nothing to do
    (tmp_path / "empty").mkdir()
    discard_run(tmp_path / "empty", ("run.json",))
    assert not (tmp_path / "empty").exists()
    notes = tmp_path / "notes"
    notes.mkdir()
    (notes / "thesis.tex").write_text("chapter 1")
    with pytest.raises(InputError, match="refusing to delete"):
        discard_run(notes, ("run.json",))
    assert (notes / "thesis.tex").exists()
