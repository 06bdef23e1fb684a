"""Model files from strangers (STYLE.md reliability checklist 5 and 6).

Every hostile file is built here from a small fitted model, then tampered with and
re-signed (its checksum recomputed), so that only the loader's own bounds stand in the
way. The corpus is loaded in one child process whose address space is limited and
whose every load has an alarm, so a regression fails a test instead of hanging or
swapping the suite; each load must raise ``ModelFileError`` naming the file, within
1 s and 200 MB (traced by ``tracemalloc``, which sees numpy's buffers too).
"""

from __future__ import annotations

import bz2
import copy
import functools
import hashlib
import io
import json
import os
import pickle
import struct
import subprocess
import sys
import zipfile
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from behavior_hmm.data import Dataset
from behavior_hmm.errors import ModelFileError
from behavior_hmm.models import CBLM, SBLM
from behavior_hmm.models import _modelfile as mf

MIB = 1 << 20
MAX_SECONDS = 1.0
MAX_PEAK_BYTES = 200_000_000
BOMB_MIB = 256  # more than the 200 MB a load may take, so a full decompression fails


# ---------------------------------------------------------------- zip bytes by hand
# zipfile cannot write lying headers, encrypted flags or unknown methods; this can.
@dataclass(frozen=True)
class Entry:
    name: str
    stored: bytes  # the bytes as they lie in the archive (compressed or not)
    size: int  # the uncompressed size the headers declare
    crc: int
    method: int = zipfile.ZIP_DEFLATED
    flags: int = 0


def entry(name: str, data: bytes, *, method: int = zipfile.ZIP_DEFLATED) -> Entry:
    """An honest entry holding ``data`` (deflated unless ``method`` is 0)."""
    stored = deflate(data) if method == zipfile.ZIP_DEFLATED else data
    return Entry(name, stored, len(data), zlib.crc32(data), method)


def zip_bytes(entries: list[Entry]) -> bytes:
    out = bytearray()
    directory = bytearray()
    for e in entries:
        name = e.name.encode()
        offset = len(out)
        out += struct.pack(
            "<4s5H3L2H", b"PK\x03\x04", 20, e.flags, e.method, 0, 0x21,
            e.crc, len(e.stored), e.size, len(name), 0,
        )  # fmt: skip
        out += name + e.stored
        directory += struct.pack(
            "<4s6H3L5H2L", b"PK\x01\x02", 20, 20, e.flags, e.method, 0, 0x21,
            e.crc, len(e.stored), e.size, len(name), 0, 0, 0, 0, 0o644 << 16, offset,
        )  # fmt: skip
        directory += name
    end = struct.pack(
        "<4s4H2LH", b"PK\x05\x06", 0, 0, len(entries), len(entries),
        len(directory), len(out), 0,
    )  # fmt: skip
    return bytes(out + directory + end)


def deflate(data: bytes) -> bytes:
    comp = zlib.compressobj(6, zlib.DEFLATED, -15)
    return comp.compress(data) + comp.flush()


@functools.cache
def deflated_run(head: bytes, n_mib: int, fill: bytes = b"\0") -> bytes:
    """Raw deflate of ``head`` then ``n_mib`` MiB of ``fill``, built in microseconds.

    A full flush resets the compressor, so every MiB of ``fill`` compresses to the same
    block and the stream is that block repeated (about 1 KiB per MiB).
    """
    comp = zlib.compressobj(9, zlib.DEFLATED, -15)
    start = comp.compress(head) + comp.flush(zlib.Z_FULL_FLUSH)
    block = comp.compress(fill * MIB) + comp.flush(zlib.Z_FULL_FLUSH)
    return start + block * n_mib + comp.flush()


# ------------------------------------------------------------ a model file in parts
@dataclass
class Parts:
    """A model file taken apart: its header and its arrays as ``.npy`` bytes."""

    header: dict[str, Any]
    arrays: dict[str, bytes]

    @classmethod
    def of(cls, raw: bytes) -> Parts:
        with zipfile.ZipFile(io.BytesIO(raw)) as zf:
            header = json.loads(zf.read("model.json"))
            npz = zf.read("arrays.npz")
        with zipfile.ZipFile(io.BytesIO(npz)) as zf:
            arrays = {i.filename[:-4]: zf.read(i) for i in zf.infolist()}
        return cls(header, arrays)

    def copy(self) -> Parts:
        return Parts(copy.deepcopy(self.header), dict(self.arrays))

    def array(self, name: str) -> np.ndarray:
        return np.load(io.BytesIO(self.arrays[name]))


def npy(arr: np.ndarray, version: tuple[int, int] | None = None) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, arr, version=version, allow_pickle=True)
    return buf.getvalue()


def npy_header(descr: str, shape: tuple[int, ...], version: tuple[int, int] = (1, 0)) -> bytes:
    """A ``.npy`` header alone, for shapes and dtypes numpy would never write for us."""
    buf = io.BytesIO()
    header = {"descr": descr, "fortran_order": False, "shape": shape}
    if version == (1, 0):
        np.lib.format.write_array_header_1_0(buf, header)
    else:
        np.lib.format.write_array_header_2_0(buf, header)
    return buf.getvalue()


def npz(arrays: dict[str, bytes], method: int = zipfile.ZIP_DEFLATED) -> bytes:
    return zip_bytes([entry(f"{name}.npy", data, method=method) for name, data in arrays.items()])


def pack(
    parts: Parts,
    *,
    arrays_npz: bytes | None = None,
    resign: bool = True,
    raw_json: dict[str, str] | None = None,
) -> bytes:
    """The model file of ``parts``, its checksum recomputed unless ``resign`` is false.

    ``raw_json`` maps a state field to JSON text put there verbatim (tokens that
    ``json.dumps`` would not write, such as ``Infinity`` or 5000 digits).
    """
    arrays_npz = npz(parts.arrays) if arrays_npz is None else arrays_npz
    header = copy.deepcopy(parts.header)
    if resign:
        header["arrays_sha256"] = hashlib.sha256(arrays_npz).hexdigest()
    for key in raw_json or {}:
        header["state"][key] = f"@@{key}@@"
    text = json.dumps(header, indent=1)
    for key, token in (raw_json or {}).items():
        text = text.replace(f'"@@{key}@@"', token)
    return zip_bytes(
        [entry("model.json", text.encode()), entry("arrays.npz", arrays_npz, method=0)]
    )


def with_array(parts: Parts, name: str, data: bytes) -> bytes:
    edited = parts.copy()
    edited.arrays[name] = data
    return pack(edited)


def with_state(parts: Parts, **changes: Any) -> bytes:
    edited = parts.copy()
    edited.header["state"].update(changes)
    return pack(edited)


def nested(cblm: Parts, inner: bytes, inner_name: str, levels: int) -> bytes:
    """``levels`` CBLMs wrapped around ``inner``, each the only component of the next."""
    for level in range(levels):
        outer = cblm.copy()
        state = outer.header["state"]
        state.update(kinds=["CBLM"], names=[inner_name], behavior=f"level-{level}")
        outer.arrays["component.0"] = npy(np.frombuffer(inner, dtype=np.uint8))
        inner = pack(outer)
        inner_name = f"level-{level}"
    return inner


# ------------------------------------------------------------------------ the corpus
@dataclass(eq=False)
class Corpus:
    """The valid files that the hostile ones are made from."""

    folder: Path
    sblm_raw: bytes = field(repr=False)
    cblm_raw: bytes = field(repr=False)

    @functools.cached_property
    def sblm(self) -> Parts:
        return Parts.of(self.sblm_raw)

    @functools.cached_property
    def cblm(self) -> Parts:
        return Parts.of(self.cblm_raw)

    @functools.cached_property
    def npz(self) -> dict[str, bytes]:
        """``arrays.npz`` of each kind as :func:`pack` writes it."""
        return {"SBLM": npz(self.sblm.arrays), "CBLM": npz(self.cblm.arrays)}

    def json_text(self) -> bytes:
        with zipfile.ZipFile(io.BytesIO(self.sblm_raw)) as zf:
            return zf.read("model.json")

    def arrays_npz(self) -> bytes:
        with zipfile.ZipFile(io.BytesIO(self.sblm_raw)) as zf:
            return zf.read("arrays.npz")


Builder = Callable[[Corpus], "bytes | Path"]


@dataclass(frozen=True)
class Case:
    name: str
    kind: str  # the class that loads it
    build: Builder
    loads: bool = False  # a control: a valid file that must load


CASES: list[Case] = []


def case(kind: str, *, loads: bool = False) -> Callable[[Builder], Builder]:
    """Register a builder of one file of the corpus, named after the function."""

    def register(build: Builder) -> Builder:
        CASES.append(Case(build.__name__, kind, build, loads))
        return build

    return register


def _outer(c: Corpus, json_entry: Entry | None = None, npz_entry: Entry | None = None) -> bytes:
    json_entry = json_entry or entry("model.json", c.json_text())
    npz_entry = npz_entry or entry("arrays.npz", c.arrays_npz(), method=0)
    return zip_bytes([json_entry, npz_entry])


def _json_entry_with(c: Corpus, **fields: Any) -> bytes:
    honest = entry("model.json", c.json_text())
    return _outer(c, Entry(**{**honest.__dict__, **fields}))


def _bomb(name: str, declared: int, head: bytes = b"", fill: bytes = b"\0") -> Entry:
    """A deflated entry of ``head`` + BOMB_MIB MiB of ``fill`` that declares ``declared``."""
    return Entry(name, deflated_run(head, BOMB_MIB, fill), declared, 0)


def _npz_with(c: Corpus, *extra: Entry, without: str = "") -> bytes:
    """The SBLM re-signed with ``extra`` members appended to its arrays."""
    kept = [entry(f"{k}.npy", v) for k, v in c.sblm.arrays.items() if k != without]
    return pack(c.sblm, arrays_npz=zip_bytes([*kept, *extra]))


def _npy_bomb(c: Corpus, declared: int | None) -> bytes:
    head = npy_header("<f8", (BOMB_MIB * MIB // 8,))
    size = len(head) + BOMB_MIB * MIB if declared is None else declared
    return _npz_with(c, _bomb("hmm.A_counts.npy", size, head), without="hmm.A_counts")


def _scaled(c: Corpus, name: str, factor: float) -> bytes:
    return with_array(c.sblm, name, npy(c.sblm.array(name) * factor))


def _state_field(parts: Parts, path: tuple[str, ...], value: Any) -> bytes:
    edited = parts.copy()
    target = edited.header["state"]
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = value
    return pack(edited)


def _component(c: Corpus, data: bytes, kinds: list[str] | None = None) -> bytes:
    edited = c.cblm.copy()
    edited.arrays["component.0"] = npy(np.frombuffer(data, dtype=np.uint8))
    if kinds is not None:
        edited.header["state"]["kinds"] = kinds
    return pack(edited)


# -- not a regular file, or too big on disk
@case("SBLM")
def fifo(c: Corpus) -> Path:
    path = c.folder / "fifo.bhmm"
    os.mkfifo(path)
    return path


@case("SBLM")
def directory(c: Corpus) -> Path:
    path = c.folder / "folder.bhmm"
    path.mkdir()
    return path


@case("SBLM")
def dev_zero(c: Corpus) -> Path:
    return Path("/dev/zero")


@case("SBLM")
def sparse_4_gib(c: Corpus) -> Path:
    path = c.folder / "sparse.bhmm"
    with open(path, "wb") as fh:
        fh.truncate(4 << 30)  # sparse: takes no disk
    return path


# -- the zip container
@case("SBLM")
def many_zip_entries(c: Corpus) -> bytes:
    return zip_bytes([entry(f"m{i}", b"") for i in range(20000)])


@case("SBLM")
def duplicate_member(c: Corpus) -> bytes:
    json_entry = entry("model.json", c.json_text())
    return zip_bytes([json_entry, json_entry, entry("arrays.npz", c.arrays_npz(), method=0)])


@case("SBLM")
def encrypted_flag(c: Corpus) -> bytes:
    return _json_entry_with(c, flags=1)


@case("SBLM")
def compression_99(c: Corpus) -> bytes:
    return _json_entry_with(c, method=99)


@case("SBLM")
def compression_bzip2(c: Corpus) -> bytes:
    return _json_entry_with(c, method=12, stored=bz2.compress(c.json_text()))


@case("SBLM")
def truncated_end(c: Corpus) -> bytes:
    return c.sblm_raw[:-30]


@case("SBLM")
def npz_truncated(c: Corpus) -> bytes:
    return pack(c.sblm, arrays_npz=c.arrays_npz()[: len(c.arrays_npz()) // 2])


# -- size bombs: BOMB_MIB MiB from about BOMB_MIB KiB
@case("SBLM")
def arrays_npz_deflate_bomb(c: Corpus) -> bytes:
    return _outer(c, npz_entry=_bomb("arrays.npz", BOMB_MIB * MIB))


@case("SBLM")
def model_json_lying_size(c: Corpus) -> bytes:
    return _outer(c, _bomb("model.json", 1000, fill=b" "))


@case("SBLM")
def npy_bomb_resigned(c: Corpus) -> bytes:
    return _npy_bomb(c, None)


@case("SBLM")
def npy_bomb_lying_size(c: Corpus) -> bytes:
    return _npy_bomb(c, 1000)


@case("CBLM")
def component_deflate_bomb(c: Corpus) -> bytes:
    return _component(c, _outer(c, npz_entry=_bomb("arrays.npz", BOMB_MIB * MIB)))


# -- .npy members
@case("SBLM")
def v0_dtype_1e9_by_1e9(c: Corpus) -> bytes:
    return with_array(c.sblm, "hmm.A_counts", npy_header("|V0", (10**9, 10**9)))


@case("SBLM")
def object_dtype_pickle(c: Corpus) -> bytes:
    payload = npy_header("|O", (1,)) + pickle.dumps({"x": 1})
    return with_array(c.sblm, "prim.counts", payload)


@case("SBLM")
def unicode_dtype(c: Corpus) -> bytes:
    return with_array(c.sblm, "prim.counts", npy(np.array(["run"])))


@case("SBLM")
def structured_dtype(c: Corpus) -> bytes:
    return with_array(c.sblm, "prim.counts", npy(np.zeros(3, dtype=[("a", "<f8")])))


@case("SBLM")
def complex_dtype(c: Corpus) -> bytes:
    return with_array(c.sblm, "prim.counts", npy(np.zeros(3, dtype=complex)))


@case("SBLM")
def npy_version_3(c: Corpus) -> bytes:
    return with_array(c.sblm, "hmm.A_counts", npy(c.sblm.array("hmm.A_counts"), version=(3, 0)))


@case("SBLM")
def npy_header_of_4_gib(c: Corpus) -> bytes:
    return with_array(
        c.sblm, "hmm.A_counts", b"\x93NUMPY\x02\x00" + struct.pack("<I", 2**32 - 16) + b"{"
    )


@case("SBLM")
def npy_truncated(c: Corpus) -> bytes:
    return with_array(c.sblm, "hmm.A_counts", c.sblm.arrays["hmm.A_counts"][:-8])


@case("SBLM")
def duplicate_array(c: Corpus) -> bytes:
    return _npz_with(c, entry("hmm.A_counts.npy", c.sblm.arrays["hmm.A_counts"]))


@case("SBLM")
def array_name_traversal(c: Corpus) -> bytes:
    return _npz_with(c, entry("../../evil.npy", c.sblm.arrays["hmm.A_counts"]))


# -- model.json
@case("SBLM")
def max_steps_infinity(c: Corpus) -> bytes:
    return pack(c.sblm, raw_json={"max_steps": "Infinity"})


@case("SBLM")
def max_steps_1e400(c: Corpus) -> bytes:
    return pack(c.sblm, raw_json={"max_steps": "1e400"})


@case("SBLM")
def max_steps_1e12_float(c: Corpus) -> bytes:
    return pack(c.sblm, raw_json={"max_steps": "1e12"})


@case("SBLM")
def max_steps_10_to_the_12(c: Corpus) -> bytes:
    return with_state(c.sblm, max_steps=10**12)


@case("SBLM")
def max_steps_zero(c: Corpus) -> bytes:
    return with_state(c.sblm, max_steps=0)


@case("SBLM")
def integer_of_5000_digits(c: Corpus) -> bytes:
    return pack(c.sblm, raw_json={"max_steps": "7" * 5000})


@case("SBLM")
def json_nested_100k_deep(c: Corpus) -> bytes:
    return pack(c.sblm, raw_json={"behavior": "[" * 100_000 + "]" * 100_000})


@case("SBLM")
def json_nested_30k_deep(c: Corpus) -> bytes:  # within MAX_JSON_BYTES: refused by depth
    return pack(c.sblm, raw_json={"behavior": "[" * 30_000 + "]" * 30_000})


@case("SBLM")
def json_string_of_20k_escaped_quotes(c: Corpus) -> bytes:
    return pack(c.sblm, raw_json={"behavior": '"' + '\\"' * 20_000 + '"'})


@case("SBLM")
def default_goal_string(c: Corpus) -> bytes:
    return with_state(c.sblm, default_goal="angle")


@case("SBLM")
def rest_values_nan(c: Corpus) -> bytes:
    return pack(c.sblm, raw_json={"rest_values": '{"angle": NaN}'})


@case("SBLM")
def generators_window_1e9(c: Corpus) -> bytes:
    return _state_field(c.sblm, ("generators", "window"), 10**9)


@case("SBLM")
def primitives_window_1e9(c: Corpus) -> bytes:
    return _state_field(c.sblm, ("primitives", "window"), 10**9)


@case("SBLM")
def edm_scale_1e_minus_200(c: Corpus) -> bytes:
    return _state_field(c.sblm, ("observations", "edm_scale"), 1e-200)


@case("SBLM")
def pipeline_range_1e_minus_12_wide(c: Corpus) -> bytes:
    return _state_field(c.sblm, ("pipeline", "ranges", "angle"), [0.0, 1e-12])


# -- arrays with values out of range
@case("SBLM")
def weights_1e300(c: Corpus) -> bytes:
    return _scaled(c, "gen.coef_0", 1e300)


@case("SBLM")
def prototypes_1e300(c: Corpus) -> bytes:
    return _scaled(c, "prim.prototypes", 1e300)


@case("SBLM")
def start_envelope_negative(c: Corpus) -> bytes:
    return _scaled(c, "start_envelope", -1.0)


@case("SBLM")
def start_envelope_nan(c: Corpus) -> bytes:
    envelope = c.sblm.array("start_envelope").copy()
    envelope[0, 0] = np.nan
    return with_array(c.sblm, "start_envelope", npy(envelope))


@case("SBLM")
def start_envelope_one_command_short(c: Corpus) -> bytes:
    return with_array(c.sblm, "start_envelope", npy(c.sblm.array("start_envelope")[:, :1]))


@case("SBLM")
def onset_floor_beyond_one(c: Corpus) -> bytes:
    return with_array(c.sblm, "onset_floor", npy(c.sblm.array("onset_floor") + 2.0))


@case("SBLM")
def onset_floor_one_primitive_short(c: Corpus) -> bytes:
    return with_array(c.sblm, "onset_floor", npy(c.sblm.array("onset_floor")[:-1]))


@case("SBLM")
def input_range_low_above_high(c: Corpus) -> bytes:
    ranges = c.sblm.array("input_range").copy()
    ranges[:, 0] = ranges[:, 1] + 1.0
    return with_array(c.sblm, "input_range", npy(ranges))


@case("SBLM")
def input_range_one_column_short(c: Corpus) -> bytes:
    return with_array(c.sblm, "input_range", npy(c.sblm.array("input_range")[:, :, :-1]))


@case("SBLM")
def input_range_1e300(c: Corpus) -> bytes:
    return _scaled(c, "input_range", 1e300)


@case("SBLM")
def start_range_low_above_high(c: Corpus) -> bytes:
    starts = c.sblm.array("start_range").copy()
    starts[..., 0] = starts[..., 1] + 1.0
    return with_array(c.sblm, "start_range", npy(starts))


@case("SBLM")
def start_range_one_cycle_short(c: Corpus) -> bytes:
    return with_array(c.sblm, "start_range", npy(c.sblm.array("start_range")[:, :, :-1]))


@case("SBLM")
def start_range_low_without_high(c: Corpus) -> bytes:
    starts = c.sblm.array("start_range").copy()
    starts[0, 0, -1, 1] = np.nan  # the clock's end always holds a row
    return with_array(c.sblm, "start_range", npy(starts))


@case("SBLM")
def start_range_infinite(c: Corpus) -> bytes:
    starts = c.sblm.array("start_range").copy()
    starts[0, 0, -1, 0] = -np.inf
    return with_array(c.sblm, "start_range", npy(starts))


@case("SBLM")
def start_range_1e300(c: Corpus) -> bytes:
    return _scaled(c, "start_range", 1e300)


@case("SBLM")
def counts_beyond_int64(c: Corpus) -> bytes:
    counts = c.sblm.array("prim.counts").astype(np.uint64) + np.uint64(2**63)
    return with_array(c.sblm, "prim.counts", npy(counts))


# -- CBLM
@case("CBLM")
def cblm_command_scale_zero(c: Corpus) -> bytes:
    return with_state(c.cblm, command_scale=0)


@case("CBLM")
def cblm_command_scale_negative(c: Corpus) -> bytes:
    return with_state(c.cblm, command_scale=-3.0)


@case("CBLM")
def cblm_nested_40_deep(c: Corpus) -> bytes:
    return nested(c.cblm, c.cblm_raw, "turn-only", 40)


@case("CBLM")
def cblm_nested_one_past_the_bound(c: Corpus) -> bytes:
    return nested(c.cblm, c.cblm_raw, "turn-only", mf.MAX_NESTING)


@case("CBLM")
def component_pickle(c: Corpus) -> bytes:
    return _component(c, pickle.dumps({"kind": "SBLM"}))


@case("CBLM")
def component_kind_lies(c: Corpus) -> bytes:
    return _component(c, c.sblm_raw, kinds=["CBLM"])


# -- controls: valid files, loaded by the same child
@case("SBLM", loads=True)
def valid_sblm(c: Corpus) -> bytes:
    return c.sblm_raw


@case("CBLM", loads=True)
def valid_cblm(c: Corpus) -> bytes:
    return c.cblm_raw


@case("SBLM", loads=True)
def repacked_sblm(c: Corpus) -> bytes:  # the zip writer above writes loadable files
    return pack(c.sblm)


@case("CBLM", loads=True)
def repacked_cblm(c: Corpus) -> bytes:
    return pack(c.cblm)


@case("CBLM", loads=True)
def cblm_nested_at_the_bound(c: Corpus) -> bytes:
    # the turn SBLM inside the tiny CBLM ends MAX_NESTING levels deep
    return nested(c.cblm, c.cblm_raw, "turn-only", mf.MAX_NESTING - 1)


@pytest.fixture(scope="module")
def corpus(
    tmp_path_factory: pytest.TempPathFactory, turn_model: SBLM, turn_data: Dataset
) -> Corpus:
    folder = tmp_path_factory.mktemp("hostile")
    turn_model.save(folder / "turn.bhmm")
    tagged = Dataset.from_episodes(
        [{**ep.to_dict(), "behavior": "turn"} for ep in turn_data.episodes()],
        metadata={"behavior": "turn-only"},
    )
    CBLM([turn_model], inputs=("angle",)).fit(tagged).save(folder / "cblm.bhmm")
    return Corpus(folder, (folder / "turn.bhmm").read_bytes(), (folder / "cblm.bhmm").read_bytes())


# The child: limited address space, an alarm per load, one JSON line per load.
CHILD = r"""
import json, resource, signal, sys, time, tracemalloc
from behavior_hmm.models import CBLM, SBLM

with open("/proc/self/statm") as fh:
    used = int(fh.read().split()[0]) * resource.getpagesize()
limit = used + int(sys.argv[2])
_, hard = resource.getrlimit(resource.RLIMIT_AS)
if hard != resource.RLIM_INFINITY:
    limit = min(limit, hard)
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
loaders = {"SBLM": SBLM, "CBLM": CBLM}
tracemalloc.start()
for name, kind, path in json.loads(sys.argv[1]):
    print(json.dumps({"case": name, "started": True}), flush=True)
    signal.alarm(10)  # default action: the child dies and the parent reports a hang
    tracemalloc.reset_peak()
    before = tracemalloc.get_traced_memory()[0]
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    start = time.perf_counter()
    try:
        loaders[kind].load(path)
        error, message = None, ""
    except Exception as err:
        error, message = type(err).__name__, str(err)
    seconds = time.perf_counter() - start
    signal.alarm(0)
    peak = tracemalloc.get_traced_memory()[1] - before
    rss_growth = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss) * 1024
    print(json.dumps({"case": name, "error": error, "message": message, "seconds": seconds,
                      "peak_bytes": peak, "rss_growth": rss_growth}), flush=True)
"""


@pytest.fixture(scope="module")
def outcomes(corpus: Corpus) -> dict[str, dict[str, Any]]:
    return run_corpus(corpus)


def run_corpus(corpus: Corpus) -> dict[str, dict[str, Any]]:
    """Build every case and load it in the child; the outcome of each case by name."""
    jobs = []
    for item in CASES:
        built = item.build(corpus)
        if isinstance(built, bytes):
            path = corpus.folder / f"{item.name}.bhmm"
            path.write_bytes(built)
            built = path
        jobs.append([item.name, item.kind, str(built)])
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    proc = subprocess.run(
        [sys.executable, "-c", CHILD, json.dumps(jobs), str(1 << 30)],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )
    results: dict[str, dict[str, Any]] = {}
    for line in proc.stdout.splitlines():
        record = json.loads(line)
        results[record["case"]] = record
    died = f"child exited with {proc.returncode}: {proc.stderr[-500:]}"
    for name, record in results.items():
        if record.get("started"):  # the child died in this load (alarm or crash)
            results[name] = {"error": f"died in this load; {died}"}
    for name, _kind, path in jobs:
        results.setdefault(name, {"error": f"not reached; {died}"})["path"] = path
    return results


@pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="FIFOs, /dev/zero and RLIMIT_AS are Linux's"
)
@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_hostile_file_is_refused_quickly_and_cheaply(
    case: Case, outcomes: dict[str, dict[str, Any]]
) -> None:
    result = outcomes[case.name]
    if case.loads:
        assert result["error"] is None, result
    else:
        assert result["error"] == "ModelFileError", result
        assert result["message"].startswith(result["path"] + ":"), result
        assert len(result["message"].splitlines()) == 1, result
    assert result["seconds"] < MAX_SECONDS, result
    assert result["peak_bytes"] < MAX_PEAK_BYTES, result
    assert result["rss_growth"] < MAX_PEAK_BYTES, result


# ------------------------------------------------------------------------ fuzzing
def _paths(value: Any, prefix: tuple[Any, ...] = ()) -> Iterator[tuple[Any, ...]]:
    """Every key path inside ``value`` (dict keys and list indices)."""
    items = value.items() if isinstance(value, dict) else enumerate(value)
    for key, inner in items:
        yield (*prefix, key)
        if isinstance(inner, dict | list):
            yield from _paths(inner, (*prefix, key))


JSON_VALUES = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(10**20), 10**20)
    | st.floats()
    | st.text(max_size=8)
    | st.sampled_from([0, -1, 1, 3, 10**12, 1e-300, 1e300, "angle", "distance", "SBLM", "CBLM"]),
    lambda inner: (
        st.lists(inner, max_size=3)
        | st.dictionaries(st.sampled_from(["angle", "distance", "window", ""]), inner, max_size=3)
    ),
    max_leaves=8,
)


@settings(
    max_examples=80,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(data=st.data())
def test_fuzzed_model_json_loads_or_is_refused(corpus: Corpus, data: st.DataObject) -> None:
    kind = data.draw(st.sampled_from(["SBLM", "CBLM"]), label="kind")
    parts = (corpus.sblm if kind == "SBLM" else corpus.cblm).copy()
    paths = sorted(_paths(parts.header), key=repr)
    for _ in range(data.draw(st.integers(1, 3), label="edits")):
        path = data.draw(st.sampled_from(paths), label="path")
        target = parts.header
        try:
            for key in path[:-1]:
                target = target[key]
            if data.draw(st.booleans(), label="delete"):
                del target[path[-1]]
            else:
                target[path[-1]] = data.draw(JSON_VALUES, label="value")
        except (KeyError, IndexError, TypeError):
            continue  # an earlier edit removed or replaced this path
    file = corpus.folder / f"fuzz-{kind}.bhmm"
    file.write_bytes(pack(parts, arrays_npz=corpus.npz[kind]))  # re-signed
    loader = SBLM if kind == "SBLM" else CBLM
    try:
        model = loader.load(file)
    except ModelFileError as err:
        assert str(err).startswith(f"{file}:") and len(str(err).splitlines()) == 1
        return
    assert isinstance(model, loader)


def test_save_refuses_what_load_would_refuse(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(mf, "MAX_ARRAY_BYTES", 1000)
    with pytest.raises(ModelFileError, match="MAX_ARRAY_BYTES"):
        mf.dump(tmp_path / "big.bhmm", "SBLM", {}, {}, {"big": np.zeros(200)})
    assert not (tmp_path / "big.bhmm").exists()
