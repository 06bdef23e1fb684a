"""The ``.bhmm`` model file: a zip of ``model.json`` + ``arrays.npz``, never pickle.

Layout (format ``behavior-hmm-model``, version 2):

- ``model.json``: ``{"format", "version", "kind", "params", "state", "arrays_sha256"}``;
  ``kind`` is ``"SBLM"`` or ``"CBLM"``; ``params`` the constructor parameters; ``state``
  the learned non-array state; ``arrays_sha256`` the SHA-256 of ``arrays.npz``.
- ``arrays.npz``: every learned array (``.npy`` members of numeric dtype, no pickle).
  A CBLM stores each component's model file, byte for byte, as a ``uint8`` array. The
  Behavior-HMM stores its counts only, A, B and C as compressed sparse rows (see
  :meth:`~behavior_hmm.hmm.BehaviorHMM.to_arrays`).

Version 1 stored every Behavior-HMM table densely, probabilities beside counts (an
(M, M) table for M observation categories). It is refused with a pointer to
``behavior-hmm upgrade``, which converts it without loss (:mod:`._upgrade`).

A file whose hash does not match, whose members differ, whose JSON or arrays are
malformed, or that is not a zip at all (e.g. a pickle renamed ``.bhmm``) is refused
with :class:`~behavior_hmm.errors.ModelFileError` before anything runs.

Model files from strangers
--------------------------
The checksum catches accidents only: whoever edits a file can recompute it. So
:func:`load` treats every file as hostile. It opens regular files only (never a FIFO
or a device), bounds every size *before* it allocates or decompresses anything, and
again while it reads, because zip headers can lie. Every refusal is a
``ModelFileError`` with a one-line message that starts with the file's path; nothing
else is raised and nothing hangs. The bounds (raise one here if a real model needs it):

- ``MAX_FILE_BYTES`` (32 MiB): the file on disk, and each embedded component.
- ``MAX_LOAD_BYTES`` (128 MiB): everything one load holds at once, components included:
  the file, each zip member (counted twice: it is copied once while read), every
  array, and the parsed JSON (counted as 32 bytes per character of text).
- ``MAX_ARRAY_BYTES`` (64 MiB): one array, e.g. the 8 million stored counts of a sparse
  table (the turn & approach CBLM of docs/results.md has 2,315 observation categories
  and 4,630 transitions among them: 37 KB where version 1 stored 86 MB of dense tables).
- ``MAX_ARRAYS`` (1024): arrays in ``arrays.npz``; ``MAX_ZIP_DIRECTORY`` (256 KiB):
  a zip's central directory, checked before ``zipfile`` parses it.
- ``MAX_JSON_BYTES`` (64 KiB; a real ``model.json`` has 2 KiB), ``MAX_JSON_DEPTH`` (32,
  checked before parsing) and ``MAX_JSON_DIGITS`` (20 digits an integer: a 64-bit seed
  fits); ``NaN``, ``Infinity`` and floats beyond the double range are refused.
- ``MAX_NESTING`` (8): components inside components (a CBLM of CBLMs ...);
  ``MAX_COMPONENTS`` (64): components of one CBLM.
- ``MAX_STEPS`` (100 000 control cycles, about 27 minutes at 16 ms): ``max_steps``,
  so a loaded model never runs without a bounded step limit.
- ``MAX_WINDOW`` (1000 readings): CobART and motion-generator windows.
- ``MAX_ABS_VALUE`` (1e6): the magnitude of every float in the arrays and the state
  (scales, rest values, weights, prototypes); ``MAX_COUNT`` (2**53): of every integer
  in the arrays.

A file that passes every check can still make its load hold about 2.5 times
``MAX_LOAD_BYTES`` at the peak (the Behavior-HMM derives its log tables from the counts,
and holds A densely: at most 2 × 64 MiB at its bound of 2,896 states); every refused file
is refused long before that.

Zip members must be stored or deflated, unencrypted and without zip64; arrays must be
``.npy`` version 1.0 or 2.0 of kind bool, int, uint or float (at most 8 bytes an item).
Then each part checks its own values (probabilities in [0, 1], scales > 0, shapes that
agree, ...) and the model checks that its parts fit together.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import math
import os
import re
import stat
import struct
import zipfile
from collections.abc import Iterator, Mapping
from typing import IO, Any, Final

import numpy as np

from behavior_hmm._atomic import atomic_write_bytes
from behavior_hmm.errors import ModelFileError

FORMAT: Final[str] = "behavior-hmm-model"
VERSION: Final[int] = 2
#: Versions :mod:`._upgrade` converts to :data:`VERSION`.
UPGRADABLE: Final[frozenset[int]] = frozenset({1})
_MEMBERS: Final[frozenset[str]] = frozenset({"model.json", "arrays.npz"})
_MIB: Final[int] = 1024 * 1024

MAX_FILE_BYTES: Final[int] = 32 * _MIB
MAX_LOAD_BYTES: Final[int] = 128 * _MIB
MAX_ARRAY_BYTES: Final[int] = 64 * _MIB
MAX_ARRAYS: Final[int] = 1024
MAX_ZIP_DIRECTORY: Final[int] = 256 * 1024
MAX_JSON_BYTES: Final[int] = 64 * 1024
MAX_JSON_DEPTH: Final[int] = 32
MAX_JSON_DIGITS: Final[int] = 20
MAX_NESTING: Final[int] = 8
MAX_COMPONENTS: Final[int] = 64
MAX_STEPS: Final[int] = 100_000
MAX_WINDOW: Final[int] = 1000
MAX_ABS_VALUE: Final[float] = 1e6
MAX_COUNT: Final[int] = 2**53

_JSON_OBJECT_BYTES: Final[int] = 32  # bytes of Python objects per character of JSON, at most
_NPY_HEADER_BYTES: Final[int] = 10_000  # numpy's own limit on a .npy header
_MAX_NDIM: Final[int] = 8
_CHUNK: Final[int] = _MIB  # bytes decompressed (or values checked) at a time
_MESSAGE_CHARS: Final[int] = 1000  # of a refusal's reason (hostile values can be long)
_ARRAY_NAME = re.compile(r"[A-Za-z0-9_.]{1,100}\.npy")
_LINE_BREAKS = re.compile(r"[\x00-\x1f\x7f\x85\u2028\u2029]")
_EOCD = struct.Struct("<4s4H2LH")  # zip end of central directory record
_EOCD_SIGNATURE: Final[bytes] = b"PK\x05\x06"
_ZIP64_LOCATOR: Final[bytes] = b"PK\x06\x07"
_ENCRYPTED: Final[int] = 0x41  # general purpose flags: encrypted, strongly encrypted


def dump(
    path: str | os.PathLike[str],
    kind: str,
    params: Mapping[str, Any],
    state: Mapping[str, Any],
    arrays: Mapping[str, np.ndarray],
) -> None:
    """Write a model file atomically; identical inputs give identical bytes.

    A model beyond the size bounds of :func:`load` is refused here, not at its next load.
    """
    atomic_write_bytes(path, dumps(kind, params, state, arrays))


def dumps(
    kind: str,
    params: Mapping[str, Any],
    state: Mapping[str, Any],
    arrays: Mapping[str, np.ndarray],
) -> bytes:
    """The bytes :func:`dump` writes."""
    if len(arrays) > MAX_ARRAYS:
        raise ModelFileError(f"{len(arrays)} arrays is more than a model file holds")
    buf = io.BytesIO()
    # Fixed member dates and sorted names keep the file byte-identical for the same model.
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as npz:
        for name in sorted(arrays):
            arr = np.ascontiguousarray(arrays[name])
            if arr.dtype == object:
                raise ModelFileError(f"array '{name}' has dtype object; refusing to save")
            if arr.nbytes > MAX_ARRAY_BYTES:
                raise ModelFileError(
                    f"array '{name}' takes {arr.nbytes} bytes, more than a model file holds "
                    f"({MAX_ARRAY_BYTES // _MIB} MiB, MAX_ARRAY_BYTES)"
                )
            member = io.BytesIO()
            np.lib.format.write_array(member, arr, allow_pickle=False)
            npz.writestr(_zipinfo(f"{name}.npy"), member.getvalue())
    arrays_bytes = buf.getvalue()
    header = {
        "format": FORMAT,
        "version": VERSION,
        "kind": kind,
        "params": params,
        "state": state,
        "arrays_sha256": hashlib.sha256(arrays_bytes).hexdigest(),
    }
    text = json.dumps(header, indent=1, sort_keys=True, allow_nan=False).encode("utf-8")
    if len(text) > MAX_JSON_BYTES:
        raise ModelFileError(f"model.json would take {len(text)} bytes (MAX_JSON_BYTES)")
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr(_zipinfo("model.json"), text)
        zf.writestr(_zipinfo("arrays.npz"), arrays_bytes, compress_type=zipfile.ZIP_STORED)
    return out.getvalue()


def _zipinfo(name: str) -> zipfile.ZipInfo:
    info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
    info.compress_type = zipfile.ZIP_DEFLATED
    info.external_attr = 0o644 << 16
    return info


# ---------------------------------------------------------------------------- reading
class Budget:
    """What one load may still use: bytes held, and how deep components are nested.

    A model file and every component inside it share one budget, so a CBLM of CBLMs
    cannot multiply the bounds by its depth.
    """

    def __init__(self) -> None:
        self.bytes_left = MAX_LOAD_BYTES
        self.depth = 0

    def take(self, n: int, what: str) -> None:
        """Count ``n`` more bytes as held; refuse past ``MAX_LOAD_BYTES``."""
        if n > self.bytes_left:
            raise ModelFileError(
                f"{what} would take the load past {MAX_LOAD_BYTES // _MIB} MiB (a size bomb?)"
            )
        self.bytes_left -= n

    @contextlib.contextmanager
    def component(self) -> Iterator[None]:
        """One level deeper into embedded components; refused past ``MAX_NESTING``."""
        if self.depth >= MAX_NESTING:
            raise ModelFileError(f"components are nested more than {MAX_NESTING} levels deep")
        self.depth += 1
        try:
            yield
        finally:
            self.depth -= 1


def refused(where: str, reason: str) -> ModelFileError:
    """The error for a refused file: ``"<where>: <reason>"`` on one line, of bounded length."""
    reason = _LINE_BREAKS.sub(" ", reason)
    if len(reason) > _MESSAGE_CHARS:
        reason = reason[: _MESSAGE_CHARS - 3] + "..."
    return ModelFileError(f"{_LINE_BREAKS.sub('?', where)}: {reason}")


def load(
    path: str | os.PathLike[str], budget: Budget | None = None
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Read and check a model file; return its header and arrays.

    Raises
    ------
    ModelFileError
        Missing, not a regular file, not a model file, corrupted, tampered with, of
        another version, or beyond one of the bounds of this module.
    """
    where = str(path)
    data = _read_regular_file(path, where)
    return loads(data, where, budget)


def loads(
    data: bytes,
    where: str,
    budget: Budget | None = None,
    versions: frozenset[int] = frozenset({VERSION}),
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """:func:`load` of a model file's bytes (e.g. a CBLM's component); ``where`` names it.

    ``versions``: the format versions accepted (the upgrade reads older ones too).
    """
    budget = Budget() if budget is None else budget
    try:
        budget.take(len(data), "the file")
        text, arrays_bytes = _read_members(data, budget)
        header = _parse_header(text, budget, versions)
        if hashlib.sha256(arrays_bytes).hexdigest() != header["arrays_sha256"]:
            raise ModelFileError("arrays do not match their checksum (corrupted or edited)")
        arrays = _read_arrays(arrays_bytes, budget)
    except ModelFileError as err:
        raise refused(where, str(err)) from None
    return header, arrays


def _read_regular_file(path: str | os.PathLike[str], where: str) -> bytes:
    """The bytes of ``path`` if it is a regular file of at most ``MAX_FILE_BYTES``."""
    # O_NONBLOCK: opening a FIFO must not wait for a writer (it is refused just below).
    flags = os.O_RDONLY | getattr(os, "O_BINARY", 0) | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(path, flags)
    except OSError as err:
        raise refused(where, f"cannot read model file ({err.strerror})") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise refused(where, "not a regular file (a model file is a plain .bhmm file)")
        if info.st_size > MAX_FILE_BYTES:
            raise refused(where, f"larger than {MAX_FILE_BYTES // _MIB} MiB")
        chunks = []
        total = 0
        while chunk := os.read(fd, _CHUNK):
            total += len(chunk)
            if total > MAX_FILE_BYTES:  # it grew while we read
                raise refused(where, f"larger than {MAX_FILE_BYTES // _MIB} MiB")
            chunks.append(chunk)
    except OSError as err:
        raise refused(where, f"cannot read model file ({err.strerror})") from None
    finally:
        os.close(fd)
    return b"".join(chunks)


def _read_members(data: bytes, budget: Budget) -> tuple[bytes, bytes]:
    """``model.json`` and ``arrays.npz`` out of the outer zip, each within its bound."""
    try:
        with _open_zip(data, "the file", len(_MEMBERS)) as zf:
            infos = zf.infolist()
            names = sorted(info.filename for info in infos)
            if set(names) != _MEMBERS or len(names) != len(_MEMBERS):
                raise ModelFileError(f"not a behavior-hmm model (members {names[:10]})")
            by_name = {info.filename: info for info in infos}
            text = _read_member(zf, by_name["model.json"], MAX_JSON_BYTES, budget)
            arrays_bytes = _read_member(zf, by_name["arrays.npz"], MAX_LOAD_BYTES, budget)
    except ModelFileError:
        raise
    except Exception as err:  # zipfile and zlib raise many types for malformed input
        raise ModelFileError(
            f"not a behavior-hmm model file ({type(err).__name__}: {err})"
        ) from None
    return text, arrays_bytes


def _open_zip(data: bytes, what: str, max_entries: int) -> zipfile.ZipFile:
    """``data`` as a zip, once its end record bounds the directory that zipfile parses."""
    # The end record is the last 22 bytes, or sits before a comment of up to 64 KiB;
    # zipfile looks for it in the same two places.
    size = _EOCD.size
    if data[-size : -size + 4] == _EOCD_SIGNATURE and data[-2:] == b"\0\0":
        start = len(data) - size
    else:
        start = data.rfind(_EOCD_SIGNATURE, max(0, len(data) - size - (1 << 16)))
    if start < 0 or len(data) - start < size:
        raise ModelFileError(f"{what} is not a zip archive")
    _, disk, dir_disk, entries_here, entries, dir_size, _, _ = _EOCD.unpack_from(data, start)
    if start >= 20 and data[start - 20 : start - 16] == _ZIP64_LOCATOR:
        raise ModelFileError(f"{what} is a zip64 archive (behavior-hmm never writes one)")
    if disk or dir_disk or entries_here != entries:
        raise ModelFileError(f"{what} is a multi-disk zip archive")
    if entries > max_entries:
        raise ModelFileError(f"{what} has {entries} zip entries (at most {max_entries})")
    if dir_size > MAX_ZIP_DIRECTORY:
        raise ModelFileError(f"{what} has a zip directory of {dir_size} bytes")
    zf = zipfile.ZipFile(io.BytesIO(data))
    if len(zf.infolist()) != entries:
        zf.close()
        raise ModelFileError(f"{what}: its zip directory disagrees with its end record")
    return zf


def _check_entry(info: zipfile.ZipInfo, limit: int) -> None:
    """Refuse an encrypted or oddly compressed zip entry, or one larger than ``limit``."""
    if info.flag_bits & _ENCRYPTED:
        raise ModelFileError(f"zip entry '{info.filename}' is encrypted")
    if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
        raise ModelFileError(
            f"zip entry '{info.filename}' uses compression method {info.compress_type} "
            "(only stored and deflated are read)"
        )
    if info.file_size > limit:
        raise ModelFileError(
            f"zip entry '{info.filename}' holds {info.file_size} bytes (at most {limit})"
        )


def _read_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, limit: int, budget: Budget) -> bytes:
    """A member's bytes, decompressed a chunk at a time and never past its declared size."""
    _check_entry(info, limit)
    budget.take(2 * info.file_size, f"zip entry '{info.filename}'")
    chunks = []
    total = 0
    with zf.open(info) as fh:
        while chunk := fh.read(_CHUNK):
            total += len(chunk)
            if total > info.file_size:
                raise ModelFileError(f"zip entry '{info.filename}' is longer than its header says")
            chunks.append(chunk)
    if total != info.file_size:
        raise ModelFileError(f"zip entry '{info.filename}' is shorter than its header says")
    return b"".join(chunks)


# ------------------------------------------------------------------------------ JSON
_JSON_SYNTAX = re.compile(r'[\[\]{}"]')
_JSON_STRING_REST = re.compile(r'[^"\\]*(?:\\.[^"\\]*)*"', re.DOTALL)


def _parse_header(text: bytes, budget: Budget, versions: frozenset[int]) -> dict[str, Any]:
    """``model.json`` parsed within the JSON bounds, with its top-level fields checked."""
    budget.take(_JSON_OBJECT_BYTES * len(text), "model.json")
    try:
        source = text.decode("utf-8")
    except UnicodeDecodeError:
        raise ModelFileError("model.json is not UTF-8 text") from None
    _check_json_depth(source)
    try:
        header = json.loads(
            source,
            parse_int=_json_int,
            parse_float=_json_float,
            parse_constant=_json_constant,
            object_pairs_hook=_json_object,
        )
    except ModelFileError:
        raise
    except (json.JSONDecodeError, RecursionError) as err:
        raise ModelFileError(f"model.json is not valid JSON ({err})") from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise ModelFileError("not a behavior-hmm model file (format field)")
    version = header.get("version")
    if type(version) is not int or version not in versions:
        hint = ""
        if type(version) is int and version in UPGRADABLE:
            hint = "; convert it with 'behavior-hmm upgrade MODEL' (lossless)"
        raise ModelFileError(
            f"model file version {_short(version)} is not supported "
            f"(this version reads {VERSION}){hint}"
        )
    for key, kind in (("kind", str), ("params", dict), ("state", dict), ("arrays_sha256", str)):
        if not isinstance(header.get(key), kind):
            raise ModelFileError(f"model.json field '{key}' is missing or malformed")
    return header


def _check_json_depth(source: str) -> None:
    """Refuse JSON nested deeper than ``MAX_JSON_DEPTH`` before parsing it (no recursion)."""
    depth = 0
    pos = 0
    while (found := _JSON_SYNTAX.search(source, pos)) is not None:
        if found.group() == '"':  # skip the whole string: brackets inside it do not nest
            end = _JSON_STRING_REST.match(source, found.end())
            if end is None:
                raise ModelFileError("model.json has an unterminated string")
            pos = end.end()
            continue
        depth += 1 if found.group() in "[{" else -1
        if depth > MAX_JSON_DEPTH:
            raise ModelFileError(f"model.json is nested more than {MAX_JSON_DEPTH} levels deep")
        pos = found.end()


def _json_int(text: str) -> int:
    if len(text.lstrip("-")) > MAX_JSON_DIGITS:
        raise ModelFileError(f"model.json has an integer of {len(text)} digits")
    return int(text)


def _json_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ModelFileError(f"model.json has a number beyond the float range ({text[:40]})")
    return value


def _json_constant(text: str) -> Any:
    raise ModelFileError(f"model.json holds {text}, which is not a number")


def _json_object(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out = dict(pairs)
    if len(out) != len(pairs):
        raise ModelFileError("model.json repeats a key in one object")
    return out


# ---------------------------------------------------------------------------- arrays
def _read_arrays(data: bytes, budget: Budget) -> dict[str, np.ndarray]:
    """Every ``.npy`` member of ``arrays.npz``, each checked before its data is read."""
    arrays: dict[str, np.ndarray] = {}
    try:
        with _open_zip(data, "arrays.npz", MAX_ARRAYS) as zf:
            for info in zf.infolist():
                if not _ARRAY_NAME.fullmatch(info.filename):
                    raise ModelFileError(f"arrays.npz holds {info.filename[:100]!r}, not an array")
                name = info.filename[: -len(".npy")]
                if name in arrays:
                    raise ModelFileError(f"arrays.npz holds array '{name}' twice")
                _check_entry(info, _NPY_HEADER_BYTES + 16 + MAX_ARRAY_BYTES)
                with zf.open(info) as fh:
                    arrays[name] = _read_npy(fh, info.file_size, name, budget)
    except ModelFileError:
        raise
    except Exception as err:  # zipfile, zlib and numpy raise many types for malformed input
        raise ModelFileError(f"arrays are malformed ({type(err).__name__}: {err})") from None
    return arrays


def _read_npy(fh: IO[bytes], size: int, name: str, budget: Budget) -> np.ndarray:
    """One ``.npy`` member of ``size`` bytes: header checked, then exactly its data."""
    magic = _read_exact(fh, 8, name)
    version = np.lib.format.read_magic(io.BytesIO(magic))
    length_format = {(1, 0): "<H", (2, 0): "<I"}.get(version)
    if length_format is None:
        raise ModelFileError(f"array '{name}' is .npy version {version} (1.0 or 2.0 expected)")
    length_bytes = _read_exact(fh, struct.calcsize(length_format), name)
    (length,) = struct.unpack(length_format, length_bytes)
    if length > _NPY_HEADER_BYTES:
        raise ModelFileError(f"array '{name}' has a header of {length} bytes")
    header = io.BytesIO(length_bytes + _read_exact(fh, length, name))
    if version == (1, 0):
        shape, fortran_order, dtype = np.lib.format.read_array_header_1_0(header)
    else:
        shape, fortran_order, dtype = np.lib.format.read_array_header_2_0(header)
    if dtype.kind not in "biuf" or dtype.itemsize > 8:
        raise ModelFileError(
            f"array '{name}' has dtype {dtype.str}; only bool, int, uint and float are read"
        )
    if len(shape) > _MAX_NDIM or any(n < 0 for n in shape):
        raise ModelFileError(f"array '{name}' has the shape {shape}")
    count = math.prod(shape)
    nbytes = count * dtype.itemsize
    if nbytes > MAX_ARRAY_BYTES:
        raise ModelFileError(
            f"array '{name}' of shape {shape} would take {nbytes} bytes "
            f"(at most {MAX_ARRAY_BYTES // _MIB} MiB)"
        )
    if 8 + len(header.getvalue()) + nbytes != size:
        raise ModelFileError(f"array '{name}': its size disagrees with its header")
    budget.take(nbytes, f"array '{name}'")
    flat = np.empty(count, dtype=dtype)
    view = flat.view(np.uint8).data
    pos = 0
    while pos < nbytes:
        chunk = fh.read(min(_CHUNK, nbytes - pos))
        if not chunk:
            raise ModelFileError(f"array '{name}' is truncated")
        view[pos : pos + len(chunk)] = chunk
        pos += len(chunk)
    _check_magnitudes(flat, name)
    return flat.reshape(shape[::-1]).T if fortran_order else flat.reshape(shape)


def _read_exact(fh: IO[bytes], n: int, name: str) -> bytes:
    data = fh.read(n)
    if len(data) != n:
        raise ModelFileError(f"array '{name}' is truncated")
    return data


def _check_magnitudes(flat: np.ndarray, name: str) -> None:
    """Refuse infinities and values beyond ``MAX_ABS_VALUE`` (floats) or ``MAX_COUNT``.

    NaN passes here: each part decides where it may appear (e.g. unused error curves).
    """
    if flat.dtype.kind == "b":
        return
    for start in range(0, flat.size, _CHUNK):
        part = flat[start : start + _CHUNK]
        if flat.dtype.kind == "f":
            if (np.abs(part) > MAX_ABS_VALUE).any():
                raise ModelFileError(
                    f"array '{name}' holds values beyond ±{MAX_ABS_VALUE:g} or infinite"
                )
        elif part.size and (int(part.max()) > MAX_COUNT or int(part.min()) < -MAX_COUNT):
            raise ModelFileError(f"array '{name}' holds integers beyond ±2**53")


# ------------------------------------------------------------------- value checks
def check_array(
    arrays: Mapping[str, np.ndarray],
    name: str,
    *,
    ndim: int | None = None,
    kind: str = "f",
    finite: bool = True,
) -> np.ndarray:
    """Fetch ``arrays[name]`` and check its dimension, dtype kind and finiteness."""
    if name not in arrays:
        raise ModelFileError(f"model file lacks array '{name}'")
    arr = arrays[name]
    if not isinstance(arr, np.ndarray):
        raise ModelFileError(f"'{name}' is not an array")
    if ndim is not None and arr.ndim != ndim:
        raise ModelFileError(f"array '{name}' has {arr.ndim} dimensions, expected {ndim}")
    if arr.dtype.kind not in kind:
        raise ModelFileError(f"array '{name}' has dtype {arr.dtype}, expected kind {kind!r}")
    if finite and arr.dtype.kind == "f" and not np.isfinite(arr).all():
        raise ModelFileError(f"array '{name}' contains NaN or infinite values")
    return arr


def check_mapping(value: Any, name: str) -> Mapping[str, Any]:
    """``value`` if it is a JSON object (a mapping)."""
    if not isinstance(value, Mapping):
        raise ModelFileError(f"{name} must be a mapping, got {_short(value)}")
    return value


def check_int(value: Any, name: str, low: int, high: int) -> int:
    """``value`` if it is an integer (not a bool, not a float) in ``[low, high]``."""
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise ModelFileError(f"{name} must be an integer in [{low}, {high}], got {_short(value)}")
    return value


def check_number(value: Any, name: str, *, positive: bool = False) -> float:
    """``value`` as a float: a finite number of magnitude <= ``MAX_ABS_VALUE`` (> 0 if asked)."""
    number = isinstance(value, int | float) and not isinstance(value, bool)
    if number and abs(value) <= MAX_ABS_VALUE and (value > 0 or not positive):
        return float(value)
    low = "0 <" if positive else f"-{MAX_ABS_VALUE:g} <="
    raise ModelFileError(
        f"{name} must be a number with {low} x <= {MAX_ABS_VALUE:g}, got {_short(value)}"
    )


def check_channel_values(
    value: Any, name: str, channels: tuple[str, ...], *, all_channels: bool = True
) -> dict[str, float]:
    """A mapping of channel to number: every channel of ``channels`` or (if not
    ``all_channels``) a non-empty part of them; each value checked by :func:`check_number`."""
    mapping = check_mapping(value, name)
    keys = set(mapping)
    if (keys != set(channels)) if all_channels else (not keys or not keys <= set(channels)):
        raise ModelFileError(
            f"{name} must give {'every' if all_channels else 'some'} channel of "
            f"{', '.join(channels)}, got {_short(sorted(keys))}"
        )
    return {c: check_number(mapping[c], f"{name} {c}") for c in channels if c in mapping}


def check_text(value: Any, name: str, *, optional: bool = False) -> str | None:
    """A one-line string of at most 4096 characters (``None`` too if ``optional``)."""
    if value is None and optional:
        return None
    if not isinstance(value, str) or len(value) > 4096 or _LINE_BREAKS.search(value):
        raise ModelFileError(f"{name} must be one line of text, got {_short(value)}")
    return value


def check_pipeline(pipeline: Any) -> None:
    """Refuse normalization ranges that are huge or so narrow that readings explode."""
    for channel, (low, high) in (pipeline.ranges or {}).items():
        if max(abs(low), abs(high)) > MAX_ABS_VALUE or high - low < 1.0 / MAX_ABS_VALUE:
            raise ModelFileError(
                f"normalization range of '{channel}' must lie within ±{MAX_ABS_VALUE:g} "
                f"and span at least {1.0 / MAX_ABS_VALUE:g}, got [{low:g}, {high:g}]"
            )


def _short(value: Any) -> str:
    """``repr(value)`` cut to 60 characters (values from a hostile file can be huge)."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
