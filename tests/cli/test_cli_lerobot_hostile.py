"""``import-lerobot`` on hostile folders: one ``error:`` line, exit 2, no traceback, no hang.

The importer's own cases are in tests/data/test_lerobot_hostile.py; these check that the
refusals reach the command line as user errors and that no output is written.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from cli_testing import Invoke, assert_user_error

from behavior_hmm import data


@pytest.fixture
def folder(turn_parquet: Path, tmp_path: Path) -> Path:
    return data.export_lerobot(data.read(turn_parquet), tmp_path / "lr")


def _set(path: Path, key: str, value: object) -> None:
    doc = json.loads(path.read_text())
    doc[key] = value
    path.write_text(json.dumps(doc))


def test_a_400_digit_fps(invoke: Invoke, folder: Path, tmp_path: Path) -> None:
    info = folder / "meta" / "info.json"
    _set(info, "fps", 10**400)
    out = tmp_path / "out.parquet"
    line = assert_user_error(
        invoke(["import-lerobot", folder, "-o", out]),
        str(info),
        "field 'fps'",
        "0 < fps <= 10000",
        "401-digit number",
    )
    assert len(line) < 300
    assert not out.exists()


def test_metadata_that_is_a_list(invoke: Invoke, folder: Path, tmp_path: Path) -> None:
    ours = folder / "meta" / "behavior_hmm.json"
    _set(ours, "metadata", ["not", "an", "object"])
    out = tmp_path / "out.parquet"
    assert_user_error(
        invoke(["import-lerobot", folder, "-o", out]),
        str(ours),
        "field 'metadata'",
        "must be a JSON object",
    )
    assert not out.exists()


def test_a_fifo_data_file(invoke: Invoke, folder: Path, tmp_path: Path) -> None:
    data_file = folder / "data" / "chunk-000" / "file-000.parquet"
    data_file.unlink()
    os.mkfifo(data_file)
    out = tmp_path / "out.parquet"
    assert_user_error(
        invoke(["import-lerobot", folder, "-o", out]),
        str(data_file),
        "a named pipe, not a regular file",
    )
    assert not out.exists()
