"""Every command's path arguments (issue 11, item 1): no output may name an input, no two
outputs may share a path, and an output that cannot be written is refused before any
work, with one line and exit code 2, every existing file left as it was."""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from cli_testing import CSV_HEADER, Invoke, assert_user_error, log_rows, write_csv, write_starts

IS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0

Args = Callable[[dict[str, Path], dict[str, Path]], list[object]]


@dataclass(frozen=True)
class Spec:
    """A command: its argv from input files and outputs, what it reads and writes."""

    args: Args
    inputs: tuple[str, ...] = ()  # input options, keys of the files dict
    outputs: dict[str, str] = field(default_factory=dict)  # output option -> extension
    folder: bool = False  # the single output "-o" is a folder of results
    cheap: bool = False  # runs in a second or two: the missing-folder case runs it


K = ("--sim", "kinematic")

SPECS: dict[str, Spec] = {
    "collect": Spec(
        lambda f, o: ["collect", "turn", *K, "--starts", f["--starts"], "-o", o["-o"]],
        ("--starts",),
        {"-o": ".parquet"},
        cheap=True,
    ),
    "import-csv": Spec(
        lambda f, o: ["import-csv", f["CSV_FILE"], "-o", o["-o"]],
        ("CSV_FILE",),
        {"-o": ".parquet"},
        cheap=True,
    ),
    "inspect": Spec(
        lambda f, o: ["inspect", f["DATA"], "--plot", o["--plot"], "--json", o["--json"]],
        ("DATA",),
        {"--plot": ".png", "--json": ".json"},
        cheap=True,
    ),
    "train simple": Spec(
        lambda f, o: [
            *("train", "simple", f["DATA"], "--inputs", "angle"),
            *("--config", f["--config"], "-o", o["-o"]),
        ],
        ("DATA", "--config"),
        {"-o": ".bhmm"},
        cheap=True,
    ),
    "train complex": Spec(
        lambda f, o: [
            *("train", "complex", f["DATA"], "--component", f["--component"]),
            *("--inputs", "angle", "--config", f["--config"], "-o", o["-o"]),
        ],
        ("DATA", "--component", "--config"),
        {"-o": ".bhmm"},
    ),
    "generate": Spec(
        lambda f, o: [
            *("generate", f["MODEL_FILE"], *K, "--start", "angle=60"),
            *("-o", o["-o"], "--plot", o["--plot"]),
        ],
        ("MODEL_FILE",),
        {"-o": ".parquet", "--plot": ".png"},
        cheap=True,
    ),
    "evaluate": Spec(
        lambda f, o: [
            *("evaluate", f["MODEL_FILE"], *K, "--starts", f["--starts"]),
            *("--baseline", "bc", "--data", f["--data"]),
            *("--json", o["--json"], "--report", o["--report"]),
        ],
        ("MODEL_FILE", "--starts", "--data"),
        {"--json": ".json", "--report": ".html"},
        cheap=True,
    ),
    "experiment simple": Spec(
        lambda f, o: ["experiment", "simple", *K, "--config", f["--config"], "-o", o["-o"]],
        ("--config",),
        {"-o": ""},
        folder=True,
    ),
    "experiment complex": Spec(
        lambda f, o: ["experiment", "complex", *K, "--config", f["--config"], "-o", o["-o"]],
        ("--config",),
        {"-o": ""},
        folder=True,
    ),
    "experiment categorization": Spec(
        lambda f, o: ["experiment", "categorization", *K, "-o", o["-o"]],
        outputs={"-o": ""},
        folder=True,
    ),
    "experiment generators": Spec(
        lambda f, o: ["experiment", "generators", *K, "--epochs", "1", "-o", o["-o"]],
        outputs={"-o": ""},
        folder=True,
    ),
    "experiment ablation": Spec(
        lambda f, o: ["experiment", "ablation", *K, "--task", "turn", "-o", o["-o"]],
        outputs={"-o": ""},
        folder=True,
    ),
    "experiment faults": Spec(
        lambda f, o: ["experiment", "faults", *K, "--task", "turn", "-o", o["-o"]],
        outputs={"-o": ""},
        folder=True,
    ),
    "import-bag": Spec(
        lambda f, o: ["import-bag", f["BAG"], "--map", "angle=/bearing:data", "-o", o["-o"]],
        ("BAG",),
        {"-o": ".parquet"},
    ),
    "import-lerobot": Spec(
        lambda f, o: [
            *("import-lerobot", f["FOLDER"], "--map", "angle=observation.state:0"),
            *("-o", o["-o"]),
        ],
        ("FOLDER",),
        {"-o": ".parquet"},
    ),
    "export-lerobot": Spec(
        lambda f, o: ["export-lerobot", f["DATA"], o["FOLDER"]],
        ("DATA",),
        {"FOLDER": ""},
        folder=True,
    ),
    "bench": Spec(
        lambda f, o: ["bench", "sim", "--quick", "--json", o["--json"]],
        outputs={"--json": ".json"},
    ),
    "demo": Spec(lambda f, o: ["demo", *K, "-o", o["-o"]], outputs={"-o": ""}, folder=True),
}


@pytest.fixture
def files(tmp_path: Path, turn_parquet: Path, turn_bhmm: Path) -> dict[str, Path]:
    """Fresh copies of every input a command may read, by option."""
    inputs = tmp_path / "in"
    inputs.mkdir()
    data = Path(shutil.copy(turn_parquet, inputs / "turn.parquet"))
    model = Path(shutil.copy(turn_bhmm, inputs / "turn.bhmm"))
    component = Path(shutil.copy(turn_bhmm, inputs / "component.bhmm"))
    config = inputs / "params.toml"
    config.write_text('preset = "default"\n', encoding="utf-8")
    return {
        "--starts": write_starts(inputs / "starts.csv", "angle", "60"),
        "CSV_FILE": write_csv(inputs / "log.csv", CSV_HEADER, log_rows()),
        "DATA": data,
        "--data": data,
        "--config": config,
        "--component": component,
        "MODEL_FILE": model,
        "BAG": _file(inputs / "log.bag", b"not read: paths are checked first"),
        "FOLDER": _folder(inputs / "lerobot"),
    }


def _file(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path


def _folder(path: Path) -> Path:
    path.mkdir()
    return path


def _outputs(spec: Spec, folder: Path) -> dict[str, Path]:
    """A fresh path for every output of ``spec`` inside ``folder``."""
    return {option: folder / f"out{k}{ext}" for k, (option, ext) in enumerate(spec.outputs.items())}


def _snapshot(root: Path) -> dict[str, bytes | None]:
    """Every path under ``root`` with its bytes (None for folders), hidden files included."""
    out: dict[str, bytes | None] = {}
    for path in sorted(root.rglob("*")):
        out[str(path.relative_to(root))] = None if path.is_dir() else path.read_bytes()
    return out


def _refused(invoke: Invoke, args: list[object], root: Path, *needles: str) -> str:
    """The command is refused with one line, having run and written nothing."""
    before = _snapshot(root)
    result = invoke(args)
    line = assert_user_error(result, *needles)
    assert result.stdout == "", result.stdout  # no progress bar: refused before any work
    assert _snapshot(root) == before  # every input and old output as it was, no temp file
    return line


def _cases(kind: str) -> list[tuple[str, str, str]]:
    """(command, output option, input option) for the cases of ``kind``."""
    out = []
    for name, spec in SPECS.items():
        for option in spec.outputs:
            if kind == "input":
                out += [(name, option, source) for source in spec.inputs]
            elif kind == "linked input" and spec.inputs:
                out.append((name, option, spec.inputs[0]))
            elif kind in ("file", "folder", "read-only") or (kind == "missing" and spec.cheap):
                out.append((name, option, ""))
    return out


def _ids(case: tuple[str, str, str]) -> str:
    return " ".join(part for part in case if part)


@pytest.mark.parametrize("case", _cases("input"), ids=_ids)
def test_an_output_that_names_an_input_is_refused(
    invoke: Invoke, tmp_path: Path, files: dict[str, Path], case: tuple[str, str, str]
) -> None:
    name, option, source = case
    spec = SPECS[name]
    outputs = _outputs(spec, tmp_path)
    for path in outputs.values():  # old outputs: they must survive too
        if not spec.folder:
            path.write_bytes(b"old")
    outputs[option] = files[source]
    if spec.folder:  # a folder of results over an input file
        _refused(invoke, spec.args(files, outputs), tmp_path, option, "not a folder")
    else:
        _refused(invoke, spec.args(files, outputs), tmp_path, option, "overwrite", source)


@pytest.mark.parametrize("link", ["symlink", "hard link"])
@pytest.mark.parametrize(
    "case", [c for c in _cases("linked input") if not SPECS[c[0]].folder], ids=_ids
)
def test_an_output_linked_to_an_input_is_refused(
    invoke: Invoke, tmp_path: Path, files: dict[str, Path], case: tuple[str, str, str], link: str
) -> None:
    name, option, source = case
    spec = SPECS[name]
    outputs = _outputs(spec, tmp_path)
    if link == "hard link" and files[source].is_dir():
        pytest.skip("a folder cannot be hard-linked")
    alias = tmp_path / f"alias{files[source].suffix}"
    if link == "symlink":
        alias.symlink_to(files[source])
    else:
        os.link(files[source], alias)
    outputs[option] = alias
    _refused(invoke, spec.args(files, outputs), tmp_path, option, "overwrite")


@pytest.mark.parametrize("name", [n for n, s in SPECS.items() if len(s.outputs) > 1])
def test_two_outputs_on_one_path_are_refused(
    invoke: Invoke, tmp_path: Path, files: dict[str, Path], name: str
) -> None:
    spec = SPECS[name]
    first, second = spec.outputs
    outputs = _outputs(spec, tmp_path)
    shared = outputs[first].with_suffix(".png")  # a plot name, so only the clash is wrong
    shared.write_bytes(b"old")
    outputs[first] = outputs[second] = shared
    _refused(invoke, spec.args(files, outputs), tmp_path, first, second, "same file")
    # the same file through a symlink in another folder
    other = tmp_path / "other"
    other.mkdir()
    (other / "link.png").symlink_to(shared)
    outputs[second] = other / "link.png"
    _refused(invoke, spec.args(files, outputs), tmp_path, "same file")


@pytest.mark.parametrize("case", _cases("file"), ids=_ids)
def test_an_output_under_a_file_is_refused(
    invoke: Invoke, tmp_path: Path, files: dict[str, Path], case: tuple[str, str, str]
) -> None:
    """A folder that is a file: what a read-only folder is to root, who may write anywhere."""
    name, option, _ = case
    spec = SPECS[name]
    blocker = tmp_path / "somefile.txt"
    blocker.write_text("not a folder")
    outputs = _outputs(spec, tmp_path)
    for path in outputs.values():
        if not spec.folder:
            path.write_bytes(b"old")
    outputs[option] = blocker / "sub" / f"out{spec.outputs[option]}"
    _refused(invoke, spec.args(files, outputs), tmp_path, option, "somefile.txt", "not a folder")


@pytest.mark.parametrize("case", _cases("folder"), ids=_ids)
def test_an_output_of_the_wrong_kind_is_refused(
    invoke: Invoke, tmp_path: Path, files: dict[str, Path], case: tuple[str, str, str]
) -> None:
    """A file output that is a folder; a folder of results that is a file."""
    name, option, _ = case
    spec = SPECS[name]
    outputs = _outputs(spec, tmp_path)
    for path in outputs.values():
        if not spec.folder:
            path.write_bytes(b"old")
    if spec.folder:
        outputs[option] = tmp_path / "results.txt"
        outputs[option].write_text("a file")
        _refused(invoke, spec.args(files, outputs), tmp_path, option, "not a folder")
    else:
        outputs[option] = tmp_path / f"folder{spec.outputs[option]}"
        outputs[option].mkdir()
        _refused(invoke, spec.args(files, outputs), tmp_path, option, "is a folder")


@pytest.mark.parametrize("case", _cases("read-only"), ids=_ids)
def test_an_output_in_a_read_only_folder_is_refused(
    invoke: Invoke,
    tmp_path: Path,
    files: dict[str, Path],
    case: tuple[str, str, str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    name, option, _ = case
    spec = SPECS[name]
    locked = tmp_path / "locked"
    locked.mkdir()
    if IS_ROOT:  # root ignores chmod: have the check see the folder as a user would
        real_access = os.access

        def access(path: object, mode: int, **kwargs: object) -> bool:
            if Path(str(path)) == locked and mode & os.W_OK:
                return False
            return real_access(path, mode, **kwargs)  # type: ignore[arg-type]

        monkeypatch.setattr("behavior_hmm._paths.os.access", access)
    outputs = _outputs(spec, tmp_path)
    outputs[option] = locked / "sub" / f"out{spec.outputs[option]}"
    locked.chmod(0o555)
    try:
        _refused(invoke, spec.args(files, outputs), tmp_path, option, "read-only")
        outputs[option] = locked / f"out{spec.outputs[option]}"
        _refused(invoke, spec.args(files, outputs), tmp_path, option, "read-only")
    finally:
        locked.chmod(0o755)


@pytest.mark.parametrize("case", _cases("missing"), ids=_ids)
def test_an_output_in_a_missing_folder_is_written_there(
    invoke: Invoke, tmp_path: Path, files: dict[str, Path], case: tuple[str, str, str]
) -> None:
    """Missing folders under a writable one are created (as the docs' examples need:
    ``collect turn -o data/turn.parquet`` in a fresh checkout)."""
    name, option, _ = case
    spec = SPECS[name]
    outputs = _outputs(spec, tmp_path)
    outputs[option] = tmp_path / "new" / "sub" / f"out{spec.outputs[option]}"
    result = invoke(spec.args(files, outputs))
    assert result.exit_code in (0, 1), result.output  # generate: 1 = missed the goal
    assert outputs[option].stat().st_size > 0
    assert [p.name for p in outputs[option].parent.iterdir()] == [outputs[option].name]


@pytest.mark.parametrize(
    ("name", "extension"),
    [("inspect", ".txt"), ("generate", ".parquet"), ("generate", "")],
)
def test_a_plot_must_have_an_extension_matplotlib_writes(
    invoke: Invoke, tmp_path: Path, files: dict[str, Path], name: str, extension: str
) -> None:
    spec = SPECS[name]
    outputs = _outputs(spec, tmp_path)
    outputs["--plot"] = tmp_path / f"plot{extension}"
    if name == "generate":
        outputs["-o"] = tmp_path / "trace.parquet"
    _refused(invoke, spec.args(files, outputs), tmp_path, "--plot", "plot")


def test_a_plot_is_written_in_the_format_its_extension_names(
    invoke: Invoke, tmp_path: Path, files: dict[str, Path]
) -> None:
    svg = tmp_path / "run.svg"
    result = invoke(["generate", files["MODEL_FILE"], *K, "--start", "angle=60", "--plot", svg])
    assert result.exit_code in (0, 1), result.output
    assert svg.read_text(encoding="utf-8").lstrip().startswith("<?xml")
