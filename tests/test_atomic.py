import pytest

from xted import atomic
from xted.atomic import atomic_path
from xted.errors import InputError


def _write_folder(path, text):
    path.mkdir()
    (path / "data.txt").write_text(text)


@pytest.mark.parametrize("exchange", [True, False])
def test_a_folder_is_replaced_whole(tmp_path, monkeypatch, exchange):
    if not exchange:
        monkeypatch.setattr(atomic, "_exchange", lambda a, b: False)
    target = tmp_path / "out"
    _write_folder(target, "old")
    with atomic_path(target) as tmp:
        _write_folder(tmp, "new")
    assert (target / "data.txt").read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_failed_write_keeps_the_old_folder(tmp_path):
    target = tmp_path / "out"
    _write_folder(target, "old")
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        _write_folder(tmp, "half")
        raise RuntimeError("crash while writing")
    assert (target / "data.txt").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_the_exchange_swaps_both_ways(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    _write_folder(a, "A")
    _write_folder(b, "B")
    assert atomic._exchange(a, b)  # Linux (our CI and development machines) has renameat2
    assert (a / "data.txt").read_text() == "B" and (b / "data.txt").read_text() == "A"


def test_a_file_is_replaced(tmp_path):
    target = tmp_path / "x.txt"
    target.write_text("old")
    with atomic_path(target) as tmp:
        tmp.write_text("new")
    assert target.read_text() == "new"


def test_a_failed_write_leaves_no_folder_it_made(tmp_path):
    with pytest.raises(RuntimeError), atomic_path(tmp_path / "new" / "deeper" / "out.txt") as tmp:
        tmp.write_text("half")
        raise RuntimeError("crash while writing")
    assert list(tmp_path.iterdir()) == []


def test_a_refusal_of_the_file_system_names_the_target(tmp_path):
    (tmp_path / "file").write_text("a file, not a folder")
    with pytest.raises(InputError, match="cannot write .*file/out.txt"), atomic_path(tmp_path / "file" / "out.txt") as tmp:
        tmp.write_text("never")
    assert [p.name for p in tmp_path.iterdir()] == ["file"]
