"""One safe way to read a file the user hands us (issue: every reader as hard as the
model loader).

Every reader of the package (Parquet datasets, LeRobot folders, ROS bags, CSV logs, the
JSON and TOML side files) opens its inputs through these functions, so each file is:

- a **regular file** (symlinks resolved and checked): a FIFO, a device such as
  ``/dev/zero``, a socket or a folder is refused *before* it is read, and never waited
  on (opened with ``O_NONBLOCK``, then checked with ``fstat``);
- **bounded before it is allocated**: its size on disk is checked against a stated limit,
  and again while it is read (a file that grows is refused at the limit);
- for text, **bounded per line** (``MAX_LINE_CHARS``) and **per nesting level**
  (``MAX_NESTING_DEPTH``, checked by a scan, never by recursion).

A refusal is the caller's error class (:class:`~behavior_hmm.errors.DatasetError` for
data, :class:`~behavior_hmm.errors.ConfigError` for options and side files) with one
line that starts with the file's path. The bounds, stated once:

- ``MAX_TEXT_BYTES`` (256 MiB): a CSV log or any other text file read whole.
- ``MAX_SIDE_FILE_BYTES`` (4 MiB): a JSON or TOML side file (``info.json``,
  ``behavior_hmm.json``, ``--map-file``, ``--config``, a bag's ``metadata.yaml``).
- ``MAX_LINE_CHARS`` (1 MiB): one line of a text file.
- ``MAX_NESTING_DEPTH`` (32): brackets and braces nested in a JSON or TOML document.
"""

from __future__ import annotations

import json
import os
import re
import stat
from collections.abc import Callable
from pathlib import Path
from typing import Any, Final

from behavior_hmm.errors import BehaviorHMMError, ConfigError, DatasetError

_MIB: Final[int] = 1024 * 1024

#: A text file read whole (a CSV log).
MAX_TEXT_BYTES: Final[int] = 256 * _MIB
#: A JSON, TOML or YAML side file.
MAX_SIDE_FILE_BYTES: Final[int] = 4 * _MIB
#: One line of a text file (characters).
MAX_LINE_CHARS: Final[int] = _MIB
#: Brackets and braces nested in a JSON or TOML document.
MAX_NESTING_DEPTH: Final[int] = 32

_CHUNK: Final[int] = _MIB

#: Makes the caller's error from a one-line reason and the file's name.
ErrorFactory = Callable[[str, str], BehaviorHMMError]


def dataset_error(reason: str, file: str) -> BehaviorHMMError:
    """A :class:`DatasetError` naming ``file``."""
    return DatasetError(reason, file=file)


def config_error(reason: str, file: str) -> BehaviorHMMError:
    """A :class:`ConfigError` whose line starts with ``file``."""
    return ConfigError(f"{file}: {reason}")


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a named pipe"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a plain file"


def check_regular(
    path: str | os.PathLike[str], *, file: str | None = None, error: ErrorFactory = dataset_error
) -> Path:
    """``path`` with its symlinks resolved, if it names an existing regular file.

    Nothing is opened: use it for files another library opens itself (a Parquet file
    pyarrow reads, a bag rosbags reads).

    Raises
    ------
    BehaviorHMMError
        (``error``'s class) naming ``file`` (default: ``path``) if it is missing, a
        folder, a FIFO, a device or a socket, or its symlinks loop.
    """
    where = os.fspath(path) if file is None else file
    try:
        resolved = Path(path).resolve(strict=True)
        info = os.stat(resolved)
    except FileNotFoundError:
        raise error("no such file", where) from None
    except (OSError, RuntimeError) as exc:  # RuntimeError: a symlink loop (Python < 3.13)
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise error(f"cannot read file ({reason})", where) from None
    if not stat.S_ISREG(info.st_mode):
        raise error(f"{_kind(info.st_mode)}, not a regular file; give a file", where)
    return resolved


def read_bytes(
    path: str | os.PathLike[str],
    *,
    limit: int,
    file: str | None = None,
    error: ErrorFactory = dataset_error,
) -> bytes:
    """The bytes of the regular file ``path``, refused past ``limit`` bytes.

    Opens with ``O_NONBLOCK`` (a FIFO never blocks the open), checks the open file
    descriptor with ``fstat`` (so a file swapped after :func:`check_regular` is checked
    too), checks the size before reading and counts while reading.
    """
    where = os.fspath(path) if file is None else file
    resolved = check_regular(path, file=where, error=error)
    flags = os.O_RDONLY | getattr(os, "O_BINARY", 0) | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(resolved, flags)
    except OSError as exc:
        raise error(f"cannot read file ({exc.strerror or exc})", where) from None
    too_large = f"larger than {_size(limit)}; not a file this reader takes"
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise error(f"{_kind(info.st_mode)}, not a regular file; give a file", where)
        if info.st_size > limit:
            raise error(too_large, where)
        chunks = []
        total = 0
        while chunk := os.read(fd, _CHUNK):
            total += len(chunk)
            if total > limit:  # it grew while we read
                raise error(too_large, where)
            chunks.append(chunk)
    except OSError as exc:
        raise error(f"cannot read file ({exc.strerror or exc})", where) from None
    finally:
        os.close(fd)
    return b"".join(chunks)


_LINE_BREAK = re.compile(r"\r\n|\r|\n")


def read_text(
    path: str | os.PathLike[str],
    *,
    limit: int = MAX_TEXT_BYTES,
    max_line: int = MAX_LINE_CHARS,
    file: str | None = None,
    error: ErrorFactory = dataset_error,
) -> str:
    """The UTF-8 text of the regular file ``path`` (a leading BOM dropped).

    Refused: past ``limit`` bytes, a line longer than ``max_line`` characters, bytes that
    are not UTF-8, or a NUL character (a binary file); each refusal names the line.
    """
    where = os.fspath(path) if file is None else file
    raw = read_bytes(path, limit=limit, file=where, error=error)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"not UTF-8 text (byte {exc.start})", where) from None
    text = text.removeprefix("\ufeff")
    nul = text.find("\x00")
    if nul >= 0:
        line = len(_LINE_BREAK.findall(text, 0, nul)) + 1
        raise error(f"not a text file (NUL byte on line {line})", where)
    check_line_lengths(text, max_line=max_line, file=where, error=error)
    return text


def check_line_lengths(
    text: str, *, max_line: int = MAX_LINE_CHARS, file: str, error: ErrorFactory = dataset_error
) -> None:
    """Refuse ``text`` if one of its lines is longer than ``max_line`` characters."""
    if len(text) <= max_line:
        return
    start = 0
    line = 1
    for found in _LINE_BREAK.finditer(text):
        if found.start() - start > max_line:
            break
        start = found.end()
        line += 1
    else:
        if len(text) - start <= max_line:
            return
    raise error(f"line {line} is longer than {max_line:,} characters; not a log this reads", file)


_SYNTAX = re.compile(r"[\[\]{}\"'#\n]")
_DOUBLE_REST = re.compile(r'(?:[^"\\\n]|\\.)*"')
_SINGLE_REST = re.compile(r"[^'\n]*'")


def check_nesting(
    text: str,
    *,
    max_depth: int = MAX_NESTING_DEPTH,
    file: str,
    toml: bool = False,
    error: ErrorFactory = dataset_error,
) -> None:
    """Refuse a JSON (or, with ``toml``, TOML) document nested deeper than ``max_depth``.

    A linear scan of brackets and braces outside strings (and, for TOML, comments), run
    before the parser so that a hostile document never reaches its recursion. Strings it
    cannot follow are left to the parser, which refuses them.
    """
    depth = 0
    pos = 0
    while (found := _SYNTAX.search(text, pos)) is not None:
        char = found.group()
        pos = found.end()
        if char == '"':
            if toml and text.startswith('""', pos):  # a multi-line basic string
                end = text.find('"""', pos + 2)
                pos = len(text) if end < 0 else end + 3
                continue
            rest = _DOUBLE_REST.match(text, pos)
            pos = len(text) if rest is None else rest.end()
        elif char == "'":
            if not toml:
                continue
            if text.startswith("''", pos):  # a multi-line literal string
                end = text.find("'''", pos + 2)
                pos = len(text) if end < 0 else end + 3
                continue
            rest = _SINGLE_REST.match(text, pos)
            pos = len(text) if rest is None else rest.end()
        elif char == "#":
            if toml:
                end = text.find("\n", pos)
                pos = len(text) if end < 0 else end
        elif char == "\n":
            continue
        elif char in "[{":
            depth += 1
            if depth > max_depth:
                raise error(f"nested more than {max_depth} levels deep", file)
        else:
            depth = max(depth - 1, 0)


def load_json(
    path: str | os.PathLike[str],
    *,
    limit: int = MAX_SIDE_FILE_BYTES,
    file: str | None = None,
    error: ErrorFactory = dataset_error,
) -> Any:
    """Parse the JSON file ``path`` within the bounds above; NaN and Infinity refused."""
    where = os.fspath(path) if file is None else file
    text = read_text(path, limit=limit, max_line=limit, file=where, error=error)
    return parse_json(text, file=where, error=error)


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def parse_json(text: str, *, file: str, error: ErrorFactory = dataset_error) -> Any:
    """Parse JSON ``text`` after :func:`check_nesting`; NaN and Infinity refused."""
    check_nesting(text, file=file, error=error)
    try:
        return json.loads(text, parse_constant=_no_constant)
    except (ValueError, RecursionError) as exc:
        reason = " ".join(str(exc).split())[:160]
        raise error(f"not valid JSON ({reason})", file) from None


def load_toml(
    path: str | os.PathLike[str],
    *,
    limit: int = MAX_SIDE_FILE_BYTES,
    file: str | None = None,
    error: ErrorFactory = config_error,
) -> dict[str, Any]:
    """Parse the TOML file ``path`` within the bounds above."""
    import tomllib

    where = os.fspath(path) if file is None else file
    text = read_text(path, limit=limit, file=where, error=error)
    check_nesting(text, file=where, toml=True, error=error)
    try:
        return tomllib.loads(text)
    except (tomllib.TOMLDecodeError, RecursionError, ValueError) as exc:  # ValueError: an
        # integer of more than 4,300 digits
        reason = " ".join(str(exc).split())[:160]
        raise error(f"not valid TOML ({reason})", where) from None


def _size(n: int) -> str:
    return f"{n // _MIB} MiB" if n >= _MIB else f"{n:,} bytes"
