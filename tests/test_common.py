"""Atomic writes and provenance: a failed write leaves nothing; versions track code."""

from __future__ import annotations

import os
import stat

import pytest

from graspstab.common.io import atomic_path, read_json, write_json
from graspstab.common.provenance import code_version, stable_hash


def test_atomic_path_leaves_nothing_on_failure(tmp_path):
    target = tmp_path / "out.txt"
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("half")
        raise RuntimeError("job killed")
    assert list(tmp_path.iterdir()) == []


def test_atomic_path_keeps_old_file_until_success(tmp_path):
    target = tmp_path / "out.json"
    write_json(target, {"a": 1})
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("{broken")
        raise RuntimeError
    assert read_json(target) == {"a": 1}


def test_atomic_files_get_umask_permissions(tmp_path):
    write_json(tmp_path / "x.json", {})
    mode = stat.S_IMODE(os.stat(tmp_path / "x.json").st_mode)
    umask = os.umask(0)
    os.umask(umask)
    assert mode == 0o666 & ~umask


def test_stable_hash_ignores_key_order_but_not_values():
    assert stable_hash({"a": 1, "b": [1, 2]}) == stable_hash({"b": [1, 2], "a": 1})
    assert stable_hash({"a": 1}) != stable_hash({"a": 2})


def test_code_version_names_stage():
    assert code_version("objects") != code_version("hand")
    with pytest.raises(ValueError):
        code_version("no_such_stage")
