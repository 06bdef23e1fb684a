"""Helpers shared by the command-line tests (imported as ``cli_testing``)."""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from typer.testing import Result
from user_errors import assert_user_error as assert_user_error  # one for every package

from behavior_hmm.data import CONTROL_PERIOD, REQUIRED_COLUMNS

#: ``invoke(args)`` runs the CLI in-process (the ``invoke`` fixture).
Invoke = Callable[[Sequence[object]], Result]

#: Column order of a CSV log with our names.
CSV_HEADER: tuple[str, ...] = REQUIRED_COLUMNS


def all_commands() -> list[tuple[tuple[str, ...], Any]]:
    """Every command and group of the app, as (path of names, click command)."""
    import typer.main

    from behavior_hmm.cli import app

    found: list[tuple[tuple[str, ...], Any]] = []

    def walk(path: tuple[str, ...], command: Any) -> None:
        found.append((path, command))
        for name, sub in getattr(command, "commands", {}).items():
            walk((*path, name), sub)

    walk((), typer.main.get_command(app))
    return found


def write_starts(path: Path, header: str, *rows: str) -> Path:
    """Write a starts CSV: a header line and one line per row."""
    path.write_text("\n".join([header, *rows]) + "\n", encoding="utf-8")
    return path


def files_in(folder: Path) -> set[str]:
    """Names of everything in ``folder``, hidden temporary files included."""
    return {p.name for p in folder.iterdir()}


def digest(path: Path) -> str:
    """SHA-256 of a file's bytes."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


def log_rows(n_episodes: int = 2, n: int = 6) -> list[list[str]]:
    """Cells of a plausible CSV log (a slow turn per episode), our column order."""
    rows = []
    for ep in range(n_episodes):
        for i in range(n):
            angle = 60.0 - 10.0 * i - 5.0 * ep
            rows.append(
                [
                    str(ep),
                    f"{i * CONTROL_PERIOD:.3f}",
                    "0.5",
                    "0.0",
                    f"{angle:g}",
                    "-10.0",
                    "-0.2",
                    "0.2",
                ]
            )
    return rows


def write_csv(path: Path, header: Sequence[str], rows: Sequence[Sequence[str]]) -> Path:
    """Write a CSV log from a header and rows of cells."""
    lines = [",".join(header)] + [",".join(r) for r in rows]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def png_size(path: Path) -> tuple[int, int]:
    """(width, height) of a PNG file; fails if the file is not a PNG."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG signature"
    assert data[12:16] == b"IHDR"
    width = int.from_bytes(data[16:20], "big")
    height = int.from_bytes(data[20:24], "big")
    assert data.rstrip(b"\x00")[-8:-4] == b"IEND", "PNG has no IEND chunk (truncated?)"
    return width, height


def smooth(values: np.ndarray, fraction: float = 0.1) -> bool:
    """True if no step between consecutive values exceeds ``fraction`` of the peak."""
    peak = float(np.max(np.abs(values)))
    return peak == 0.0 or float(np.max(np.abs(np.diff(values)))) <= fraction * peak
