"""Checks of a command's path arguments, run before any work (DESIGN §4, bad input).

Every command hands :func:`check_outputs` the files and folders it reads and the paths
it will write: no output may name an input (symlinks and hard links included) or lie
inside an input folder, no two outputs may share a path, and every output must be
writable (the path is not a folder; its folder is writable, or missing and creatable:
the nearest existing parent is a writable folder). A refusal is one
:class:`~behavior_hmm.errors.ConfigError`.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Collection, Mapping, Sequence
from pathlib import Path

from behavior_hmm.errors import ConfigError

#: An input argument: one path, several (a repeatable option) or none (not given).
InputPaths = Path | Sequence[Path] | None

#: Plot formats refused although matplotlib lists them (``pgf`` needs a LaTeX install).
_UNWRITABLE_PLOT_FORMATS = frozenset({"pgf"})


def same_file(a: Path, b: Path) -> bool:
    """True when ``a`` and ``b`` name one file: equal after resolving symlinks, or the
    same inode (hard links, case-insensitive file systems) when both exist."""
    try:
        if a.resolve() == b.resolve():
            return True
    except (OSError, RuntimeError):  # a symlink loop: compare what exists
        pass
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):
        return False


@functools.cache
def plot_formats() -> tuple[str, ...]:
    """File extensions (without the dot) a plot may be written as."""
    from matplotlib.figure import Figure

    formats = Figure().canvas.get_supported_filetypes()
    return tuple(sorted(f for f in formats if f not in _UNWRITABLE_PLOT_FORMATS))


def plot_format(path: str | os.PathLike[str]) -> str:
    """The format ``path``'s extension names, or ``png`` for any other name."""
    suffix = Path(path).suffix.lower().lstrip(".")
    return suffix if suffix in plot_formats() else "png"


def check_plot_path(option: str, path: Path) -> None:
    """Refuse a plot path whose extension is not a format matplotlib writes."""
    suffix = path.suffix.lower().lstrip(".")
    formats = plot_formats()
    if not suffix:
        raise ConfigError(f"{option} {path} has no extension; e.g. {path}.png")
    if suffix not in formats:
        raise ConfigError(
            f"{option} {path}: matplotlib cannot write '.{suffix}' plots; "
            f"use one of {', '.join('.' + f for f in formats)}"
        )


def check_outputs(
    inputs: Mapping[str, InputPaths],
    outputs: Mapping[str, Path | None],
    *,
    folders: Mapping[str, Path | None] | None = None,
    plots: Collection[str] = (),
) -> None:
    """Refuse, before any work, outputs that would destroy an input or cannot be written.

    An input that is a folder (a LeRobot dataset, a ROS 2 bag), or a file the reader
    takes its whole folder for (a ROS 2 bag's ``.db3``, ``.mcap`` or ``metadata.yaml``),
    makes that folder off limits: no output file may lie inside it at any depth, and no
    output folder may be it, lie inside it or contain it (symlinks resolved, and the
    same folder under another name caught by its inode). An output folder that merely
    holds an input *file* is allowed: the commands write fixed names there
    (``results.json``, ...) or need it new or empty (``export-lerobot``).

    The output files and folders that pass are declared to :mod:`behavior_hmm._atomic`
    (:func:`~behavior_hmm._atomic.expect_outputs`): once those files are all in place
    the command's result is complete, and an interrupt after that exits 0.

    Parameters
    ----------
    inputs
        Each input argument (``"DATA"``, ``"--starts"``, ...) and the path(s) it names;
        ``None`` for an argument not given.
    outputs
        Each output file option (``"-o"``, ``"--plot"``, ...) and its path, or ``None``.
    folders
        Output options that name a folder of results (created with its parents).
    plots
        The options of ``outputs`` that are plots: their extension must be a format
        matplotlib writes.

    Raises
    ------
    ConfigError
        One line naming the option and path at fault.
    """
    from behavior_hmm._atomic import expect_outputs

    named_inputs = [(label, Path(p)) for label, value in inputs.items() for p in _as_list(value)]
    files = [(label, Path(p)) for label, p in outputs.items() if p is not None]
    dirs = [(label, Path(p)) for label, p in (folders or {}).items() if p is not None]
    for option, path in files:
        for label, source in named_inputs:
            if same_file(path, source):
                raise ConfigError(
                    f"{option} {path} would overwrite the input {label} {source}; "
                    "give another file name"
                )
    read_folders = [
        (label, source, folder)
        for label, source in named_inputs
        if (folder := _folder_read(source)) is not None
    ]
    for option, path in files + dirs:
        for label, source, folder in read_folders:
            _check_outside(option, path, label, source, folder, is_folder=(option, path) in dirs)
    for k, (option, path) in enumerate(files):
        for other, other_path in files[:k]:
            if same_file(path, other_path):
                raise ConfigError(
                    f"{other} {other_path} and {option} {path} name the same file; "
                    "give each output its own name"
                )
    for option, path in files:
        if option in plots:
            check_plot_path(option, path)
        _check_writable_file(option, path)
    for option, path in dirs:
        _check_writable_folder(option, path)
    expect_outputs([path for _, path in files], folders=bool(dirs))


#: Files of a ROS 2 bag: given one, the bag reader's input is its whole folder.
_BAG_FILE_SUFFIXES = frozenset({".db3", ".mcap", ".yaml", ".zstd"})


def _folder_read(source: Path) -> Path | None:
    """The folder an input reads from: the input itself when it is a folder, the folder
    of a ROS 2 bag's file (beside ``metadata.yaml``); None for any other input."""
    try:
        if source.is_dir():
            return source
        if (
            source.suffix.lower() in _BAG_FILE_SUFFIXES
            and (source.parent / "metadata.yaml").is_file()
        ):
            return source.parent
    except OSError:
        pass
    return None


def _check_outside(
    option: str, path: Path, label: str, source: Path, folder: Path, *, is_folder: bool
) -> None:
    """Refuse an output (file or folder) that is, lies inside or (a folder) contains the
    input folder ``folder`` (``source`` as given, or the file it was found from)."""
    named = f"the input {label} {source}"
    if folder is not source:
        named = f"the folder {folder} of the input {label} {source}"
    fix = "write outputs outside the inputs"
    if _inside(path, folder):
        relation = "is" if _inside(folder, path) else "is inside"
        raise ConfigError(f"{option} {path} {relation} {named}; {fix}")
    if is_folder and _inside(folder, path):
        raise ConfigError(f"{option} {path} contains {named}; {fix}")


def _inside(path: Path, folder: Path) -> bool:
    """True when ``path`` is ``folder`` or lies inside it at any depth: compared after
    resolving symlinks, then by inode for each existing ancestor (the same folder under
    another name: a bind mount, a case-insensitive file system)."""
    try:
        target = Path(os.path.abspath(path)).resolve()
        root = Path(os.path.abspath(folder)).resolve()
    except (OSError, RuntimeError):  # a symlink loop: nothing to compare
        return False
    if target == root or root in target.parents:
        return True
    for ancestor in (target, *target.parents):
        try:
            if os.path.samefile(ancestor, root):
                return True
        except (OSError, ValueError):  # missing yet (created by the write): look higher
            continue
    return False


def _as_list(value: InputPaths) -> list[Path]:
    if value is None:
        return []
    if isinstance(value, (str, os.PathLike)):
        return [Path(value)]
    return [Path(p) for p in value]


def _check_writable_file(option: str, path: Path) -> None:
    """The path is not a folder, and its folder exists or can be created, writable."""
    if path.is_dir():
        raise ConfigError(f"{option} {path} is a folder; give a file name")
    _check_writable_folder(option, Path(os.path.abspath(path)).parent, shown=path)


def _check_writable_folder(option: str, path: Path, shown: Path | None = None) -> None:
    """The folder exists and is writable, or its nearest existing parent is (the missing
    folders are created when the results are written)."""
    shown = path if shown is None else shown
    if path.exists() and not path.is_dir():
        raise ConfigError(f"{option} {shown}: {path} exists and is not a folder")
    folder = Path(os.path.abspath(path))
    while not folder.exists() and not folder.is_symlink() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise ConfigError(f"{option} {shown}: {folder} is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ConfigError(f"{option} {shown}: cannot write in folder {folder} (read-only)")
