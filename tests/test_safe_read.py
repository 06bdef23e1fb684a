"""The shared read guards: regular files only, sizes, lines and nesting bounded."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from behavior_hmm import _safe_read
from behavior_hmm.errors import ConfigError, DatasetError


def test_a_fifo_is_refused_without_waiting_for_a_writer(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    with pytest.raises(DatasetError, match="named pipe, not a regular file"):
        _safe_read.read_text(fifo)


def test_a_symlink_to_a_device_is_refused(tmp_path: Path) -> None:
    link = tmp_path / "zero.csv"
    link.symlink_to("/dev/zero")
    with pytest.raises(DatasetError, match=r"zero\.csv: a device, not a regular file"):
        _safe_read.read_text(link)


def test_a_folder_and_a_missing_file_are_refused(tmp_path: Path) -> None:
    with pytest.raises(DatasetError, match="a folder"):
        _safe_read.read_bytes(tmp_path, limit=10)
    with pytest.raises(DatasetError, match="no such file"):
        _safe_read.read_bytes(tmp_path / "absent", limit=10)


def test_sizes_are_bounded_before_reading(tmp_path: Path) -> None:
    big = tmp_path / "big.json"
    big.write_bytes(b" " * 101)
    with pytest.raises(ConfigError, match="larger than 100 bytes"):
        _safe_read.read_bytes(big, limit=100, error=_safe_read.config_error)
    assert _safe_read.read_bytes(big, limit=101) == b" " * 101


def test_a_long_line_is_refused_with_its_number(tmp_path: Path) -> None:
    log = tmp_path / "log.csv"
    log.write_text("a,b\n1,2\n" + "9" * 50 + "\n3,4\n")
    with pytest.raises(DatasetError, match="line 3 is longer than 40"):
        _safe_read.read_text(log, max_line=40)
    assert _safe_read.read_text(log, max_line=50).startswith("a,b")
    last = tmp_path / "last.csv"
    last.write_text("a,b\n" + "9" * 50)
    with pytest.raises(DatasetError, match="line 2 is longer"):
        _safe_read.read_text(last, max_line=40)


def test_binary_and_non_utf8_text_are_refused(tmp_path: Path) -> None:
    nul = tmp_path / "nul.csv"
    nul.write_bytes(b"a,b\n1,\x002\n")
    with pytest.raises(DatasetError, match="NUL byte on line 2"):
        _safe_read.read_text(nul)
    latin = tmp_path / "latin.csv"
    latin.write_bytes(b"a,\xe9\n")
    with pytest.raises(DatasetError, match="not UTF-8"):
        _safe_read.read_text(latin)


@pytest.mark.parametrize("opening", ["[", '{"a":'])
def test_deep_json_is_refused_before_the_parser_recurses(tmp_path: Path, opening: str) -> None:
    deep = tmp_path / "info.json"
    deep.write_text(opening * 100_000)
    with pytest.raises(DatasetError, match="nested more than 32 levels"):
        _safe_read.load_json(deep)


def test_brackets_inside_strings_do_not_count(tmp_path: Path) -> None:
    doc = tmp_path / "ok.json"
    doc.write_text('{"a": "[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[\\"[[[[[[[[[[[[[["}')
    assert _safe_read.load_json(doc) == {"a": "[" * 40 + '"' + "[" * 14}


def test_json_constants_are_refused(tmp_path: Path) -> None:
    doc = tmp_path / "nan.json"
    doc.write_text('{"fps": NaN}')
    with pytest.raises(DatasetError, match="not valid JSON"):
        _safe_read.load_json(doc)


def test_deep_toml_is_refused_and_comments_and_strings_are_skipped(tmp_path: Path) -> None:
    deep = tmp_path / "map.toml"
    deep.write_text("a = " + "[" * 5000 + "]" * 5000 + "\n")
    with pytest.raises(ConfigError, match=r"map\.toml: nested more than 32"):
        _safe_read.load_toml(deep)
    fine = tmp_path / "fine.toml"
    fine.write_text("# " + "[" * 40 + f"\n[map]\nx = \"{'{' * 40}\"\ny = '{'[' * 42}'\n")
    assert _safe_read.load_toml(fine)["map"]["y"] == "[" * 42
