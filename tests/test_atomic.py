import json

import pytest

from tax3d.atomic import atomic_write, write_json, write_text


def test_write_replaces_the_file(tmp_path):
    path = tmp_path / "a.txt"
    write_text(path, "old")
    write_text(path, "new")
    assert path.read_text() == "new"
    assert [p.name for p in tmp_path.iterdir()] == ["a.txt"]


def test_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path):
    path = tmp_path / "a.txt"
    write_text(path, "old")

    def half_then_fail(tmp):
        tmp.write_text("half")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        atomic_write(path, half_then_fail)
    assert path.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["a.txt"]


def test_write_json_returns_the_text_and_writes_it_only_when_given_a_path(tmp_path):
    text = write_json(None, {"a": [1, 2]})
    assert json.loads(text) == {"a": [1, 2]} and list(tmp_path.iterdir()) == []
    path = tmp_path / "out.json"
    assert write_json(path, {"a": 1}, indent=1) == path.read_text().rstrip("\n")
    assert path.read_text().endswith("}\n")


def test_a_failed_write_names_its_file_in_one_sentence(tmp_path):
    import errno
    import pickle

    from tax3d.atomic import WriteError, write_text

    with pytest.raises(WriteError) as raised:
        write_text(tmp_path / "gone" / "config.json", "{}")
    assert str(raised.value) == f"no such file or directory writing {tmp_path / 'gone' / 'config.json'}"
    full = WriteError(OSError(errno.ENOSPC, "No space left on device"), tmp_path / "x")
    again = pickle.loads(pickle.dumps(full))  # as it comes back from a worker process
    assert str(again) == f"no space left on device writing {tmp_path / 'x'}" and again.errno == errno.ENOSPC
