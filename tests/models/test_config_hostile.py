"""Hostile ``--config`` and ``--map-file`` TOML files: refused in one ConfigError line.

Every hostile file is built here (tmp_path); named pipes need POSIX.
"""

from __future__ import annotations

import os
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from behavior_hmm.data._mapfile import MAX_ITEMS, MAX_VALUE_CHARS, read_map_file
from behavior_hmm.errors import ConfigError
from behavior_hmm.models._config import parse_sets, read_config, resolve_params

POSIX = pytest.mark.skipif(sys.platform == "win32" or not hasattr(os, "mkfifo"), reason="POSIX")
MAX_MESSAGE = 600


def _map(path: Path) -> Any:
    return read_map_file(path, "csv")


READERS: list[Callable[[Path], Any]] = [read_config, _map]


def _refused(read: Callable[[Path], Any], path: Path, *needles: str) -> str:
    with pytest.raises(ConfigError) as caught:
        read(path)
    message = str(caught.value)
    assert "\n" not in message and len(message) < MAX_MESSAGE, message
    assert message.startswith(str(path)), message
    for needle in needles:
        assert needle in message, (needle, message)
    return message


@pytest.mark.parametrize("read", READERS)
@pytest.mark.parametrize("text", ["a = " + "[" * 5000 + "]" * 5000, "a = " + "{b = " * 3000])
def test_deep_nesting_is_refused_before_the_parser(
    tmp_path: Path, read: Callable[[Path], Any], text: str
) -> None:
    path = tmp_path / "deep.toml"
    path.write_text(text, encoding="utf-8")
    _refused(read, path, "nested more than 32 levels deep")


@pytest.mark.parametrize("read", READERS)
def test_a_huge_integer_is_refused(tmp_path: Path, read: Callable[[Path], Any]) -> None:
    path = tmp_path / "big.toml"
    path.write_text("resample = " + "9" * 5000 + "\n", encoding="utf-8")
    _refused(read, path, "not valid TOML")


@POSIX
@pytest.mark.parametrize("read", READERS)
def test_a_named_pipe_is_refused_without_waiting(
    tmp_path: Path, read: Callable[[Path], Any]
) -> None:
    fifo = tmp_path / "side.toml"
    os.mkfifo(fifo)
    caught: list[str] = []
    worker = threading.Thread(target=lambda: caught.append(_refused(read, fifo, "named pipe")))
    worker.start()
    worker.join(timeout=10)
    if worker.is_alive():
        with open(fifo, "wb"):
            pass
        worker.join()
        pytest.fail("the reader waited on a named pipe")
    assert caught


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="no /dev/zero")
@pytest.mark.parametrize("read", READERS)
def test_a_device_is_refused(tmp_path: Path, read: Callable[[Path], Any]) -> None:
    link = tmp_path / "side.toml"
    link.symlink_to("/dev/zero")
    _refused(read, link, "a device, not a regular file")


@pytest.mark.parametrize("read", READERS)
def test_a_long_line_and_a_large_file(tmp_path: Path, read: Callable[[Path], Any]) -> None:
    path = tmp_path / "side.toml"
    path.write_text('x = "' + "a" * (2 * 1024 * 1024) + '"\n', encoding="utf-8")
    _refused(read, path)
    with open(path, "wb") as fh:
        fh.truncate(5 * 1024 * 1024)
    _refused(read, path, "larger than")


def test_map_file_values_are_bounded(tmp_path: Path) -> None:
    path = tmp_path / "map.toml"
    path.write_text(f'[map]\nangle = "{"b" * (MAX_VALUE_CHARS + 1)}"\n', encoding="utf-8")
    message = _refused(_map, path, f"longer than {MAX_VALUE_CHARS} characters", "...")
    assert "b" * 100 not in message
    items = ", ".join(['"x"'] * (MAX_ITEMS + 1))
    path.write_text(f"drop = [{items}]\n", encoding="utf-8")
    _refused(_map, path, f"(limit {MAX_ITEMS:,})")
    path.write_text(f"{'k' * 10_000} = 1\n", encoding="utf-8")
    message = _refused(_map, path, "unknown key")
    assert "k" * 100 not in message
    path.write_text('delimiter = ";;"\n', encoding="utf-8")
    _refused(_map, path, "'delimiter' must be one character")
    path.write_text(f"resample = [{', '.join(['1'] * 5000)}]\n", encoding="utf-8")
    _refused(_map, path, "wrong type (got a list of 5,000 items)")


def test_config_values_are_typed_and_echoed_cut(tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    path.write_text(f'epochs = "{"e" * 10_000}"\n', encoding="utf-8")
    table = read_config(path)
    with pytest.raises(ConfigError, match="must be an integer") as caught:
        resolve_params(("SBLM",), None, table, config_name=str(path))
    assert len(str(caught.value)) < MAX_MESSAGE
    path.write_text(f"epochs = {2**70}\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="64-bit integer"):
        resolve_params(("SBLM",), None, read_config(path), config_name=str(path))
    path.write_text(f'preset = "{"p" * 10_000}"\n', encoding="utf-8")
    with pytest.raises(ConfigError, match="unknown preset") as caught:
        resolve_params(("SBLM",), None, read_config(path), config_name=str(path))
    assert len(str(caught.value)) < MAX_MESSAGE


def test_set_values_are_bounded() -> None:
    with pytest.raises(ConfigError, match="nested more than 32"):
        parse_sets(["epochs=" + "[" * 5000])
    assert parse_sets(["epochs=" + "9" * 5000])["epochs"] == "9" * 5000  # a bare word
    with pytest.raises(ConfigError) as caught:
        parse_sets(["x" * 100_000])
    assert len(str(caught.value)) < MAX_MESSAGE


_TOKENS = [*"abc_=[]{}\"'.,#0123456789+-e \n\t", "true", "map", "unit", "drop", "[map]"]
_TOMLISH = st.lists(st.sampled_from(_TOKENS), max_size=60).map("".join)


@settings(
    max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(text=_TOMLISH)
def test_arbitrary_tomlish_text(tmp_path: Path, text: str) -> None:
    path = tmp_path / "side.toml"
    path.write_text(text, encoding="utf-8")
    for read in READERS:
        try:
            read(path)
        except ConfigError as err:
            assert "\n" not in str(err) and len(str(err)) < MAX_MESSAGE


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(raw=st.binary(max_size=200))
def test_arbitrary_bytes(tmp_path: Path, raw: bytes) -> None:
    path = tmp_path / "side.toml"
    path.write_bytes(raw)
    for read in READERS:
        try:
            read(path)
        except ConfigError as err:
            assert "\n" not in str(err)
