"""The ``.bhmm`` model file: a zip of ``model.json`` + ``arrays.npz``, never pickle.

Layout (format ``behavior-hmm-model``, version 1):

- ``model.json``: ``{"format", "version", "kind", "params", "state", "arrays_sha256"}``;
  ``kind`` is ``"SBLM"`` or ``"CBLM"``; ``params`` the constructor parameters; ``state``
  the learned non-array state; ``arrays_sha256`` the SHA-256 of ``arrays.npz``.
- ``arrays.npz``: every learned array, loaded with ``allow_pickle=False``.

A file whose hash does not match, whose members differ, whose JSON or arrays are
malformed, or that is not a zip at all (e.g. a pickle renamed ``.bhmm``) is refused
with :class:`~behavior_hmm.errors.ModelFileError` before anything runs.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import zipfile
from collections.abc import Mapping
from typing import Any, Final

import numpy as np

from behavior_hmm._atomic import atomic_write_bytes
from behavior_hmm.errors import ModelFileError

FORMAT: Final[str] = "behavior-hmm-model"
VERSION: Final[int] = 1
_MEMBERS: Final[frozenset[str]] = frozenset({"model.json", "arrays.npz"})
_MAX_JSON_BYTES: Final[int] = 64 * 1024 * 1024


def dump(
    path: str | os.PathLike[str],
    kind: str,
    params: Mapping[str, Any],
    state: Mapping[str, Any],
    arrays: Mapping[str, np.ndarray],
) -> None:
    """Write a model file atomically; identical inputs give identical bytes."""
    buf = io.BytesIO()
    # Fixed member dates and sorted names keep the file byte-identical for the same model.
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as npz:
        for name in sorted(arrays):
            arr = np.ascontiguousarray(arrays[name])
            if arr.dtype == object:
                raise ModelFileError(f"array '{name}' has dtype object; refusing to save")
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
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr(_zipinfo("model.json"), text)
        zf.writestr(_zipinfo("arrays.npz"), arrays_bytes, compress_type=zipfile.ZIP_STORED)
    atomic_write_bytes(path, out.getvalue())


def load(path: str | os.PathLike[str]) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Read and check a model file; return its header and arrays.

    Raises
    ------
    ModelFileError
        Missing, not a model file, corrupted, tampered with, or another version.
    """
    where = str(path)
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except OSError as err:
        raise ModelFileError(f"{where}: cannot read model file ({err.strerror})") from None
    try:
        with zipfile.ZipFile(io.BytesIO(raw)) as zf:
            names = set(zf.namelist())
            if names != _MEMBERS:
                raise ModelFileError(f"{where}: not a behavior-hmm model (members {sorted(names)})")
            info = zf.getinfo("model.json")
            if info.file_size > _MAX_JSON_BYTES:
                raise ModelFileError(f"{where}: model.json is implausibly large")
            text = zf.read("model.json")
            arrays_bytes = zf.read("arrays.npz")
    except ModelFileError:
        raise
    except (zipfile.BadZipFile, zipfile.LargeZipFile, EOFError, ValueError, OSError) as err:
        raise ModelFileError(f"{where}: not a behavior-hmm model file ({err})") from None
    try:
        header = json.loads(text.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ModelFileError(f"{where}: model.json is not valid JSON ({err})") from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise ModelFileError(f"{where}: not a behavior-hmm model file (format field)")
    if header.get("version") != VERSION:
        raise ModelFileError(
            f"{where}: model file version {header.get('version')!r} is not supported "
            f"(this version reads {VERSION})"
        )
    for key, kind in (("kind", str), ("params", dict), ("state", dict), ("arrays_sha256", str)):
        if not isinstance(header.get(key), kind):
            raise ModelFileError(f"{where}: model.json field '{key}' is missing or malformed")
    if hashlib.sha256(arrays_bytes).hexdigest() != header["arrays_sha256"]:
        raise ModelFileError(f"{where}: arrays do not match their checksum (corrupted or edited)")
    arrays: dict[str, np.ndarray] = {}
    try:
        with np.load(io.BytesIO(arrays_bytes), allow_pickle=False) as npz:
            for name in npz.files:
                arrays[name] = np.array(npz[name])
    except Exception as err:  # numpy raises many types for malformed .npy members
        raise ModelFileError(f"{where}: arrays are malformed ({type(err).__name__})") from None
    return header, arrays


def _zipinfo(name: str) -> zipfile.ZipInfo:
    info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
    info.compress_type = zipfile.ZIP_DEFLATED
    info.external_attr = 0o644 << 16
    return info


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
    if ndim is not None and arr.ndim != ndim:
        raise ModelFileError(f"array '{name}' has {arr.ndim} dimensions, expected {ndim}")
    if arr.dtype.kind not in kind:
        raise ModelFileError(f"array '{name}' has dtype {arr.dtype}, expected kind {kind!r}")
    if finite and arr.dtype.kind == "f" and not np.isfinite(arr).all():
        raise ModelFileError(f"array '{name}' contains NaN or infinite values")
    return arr
