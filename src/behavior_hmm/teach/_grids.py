"""Default training grids (DESIGN §6) and the fixed test starts shipped with the package."""

from __future__ import annotations

import csv
import difflib
from importlib import resources
from pathlib import Path
from typing import Final

import numpy as np

from behavior_hmm.data import ARENA_MAX_DISTANCE
from behavior_hmm.errors import ConfigError

#: Distance (m) at which turn demonstrations are recorded.
TURN_DISTANCE: Final[float] = 0.5
#: Distance (m) retreat demonstrations back away to.
RETREAT_DISTANCE: Final[float] = 1.0

Start = dict[str, float]


def default_starts(behavior: str) -> list[Start]:
    """The training grid of DESIGN §6 for ``behavior``.

    turn: -180..180 deg every 10 deg (0 excluded) at 0.5 m; approach: 0.10..1.00 m
    every 0.05 m at 0 deg; turn-approach: every 20 deg x every 0.1 m plus the angle-0
    and distance-0 edges; retreat: 0.00..0.90 m every 0.05 m back to 1.0 m;
    position: every 40 deg (and 0) x start distances 0..1 m every 0.2 m x goal distances
    0, 0.25, 0.5, 0.75 and 1 m (so every goal in [0, 1] m is passed on the way).
    """
    if behavior == "turn":
        return [{"angle": float(a), "distance": TURN_DISTANCE} for a in range(-180, 181, 10) if a]
    if behavior == "approach":
        return [{"angle": 0.0, "distance": d} for d in _grid(0.10, 1.00, 0.05)]
    if behavior == "retreat":
        return [
            {"angle": 0.0, "distance": d, "goal_distance": RETREAT_DISTANCE}
            for d in _grid(0.0, 0.90, 0.05)
        ]
    if behavior == "turn-approach":
        angles = [float(a) for a in range(-180, 181, 20) if a]
        distances = _grid(0.1, 1.0, 0.1)
        starts = [{"angle": a, "distance": d} for a in angles for d in distances]
        starts += [{"angle": 0.0, "distance": d} for d in distances]
        starts += [{"angle": a, "distance": 0.0} for a in angles]
        return starts
    if behavior == "position":
        angles = [float(a) for a in range(-180, 181, 40) if a] + [0.0]
        starts = []
        for goal in (0.0, 0.25, 0.5, 0.75, 1.0):
            for d in _grid(0.0, 1.0, 0.2):
                if abs(d - goal) < 0.05:
                    continue
                starts += [{"angle": a, "distance": d, "goal_distance": goal} for a in angles]
        return starts
    raise ConfigError(f"no default grid for behavior '{behavior}'")


def test_starts(behavior: str) -> list[Start]:
    """The fixed test starts shipped in ``teach/starts/``, none on a training grid.

    15 per behavior; ``position`` has 30: 15 that need an approach, 15 a retreat.
    """
    name = f"{behavior.replace('-', '_')}_test.csv"
    ref = resources.files("behavior_hmm.teach").joinpath("starts", name)
    if not ref.is_file():
        raise ConfigError(f"no test starts shipped for behavior '{behavior}'")
    with resources.as_file(ref) as path:
        return read_starts(path)


def read_starts(path: str | Path) -> list[Start]:
    """Read a starts CSV with columns ``angle`` and/or ``distance`` (and ``goal_<channel>``).

    Raises
    ------
    DatasetError
        For a missing or unreadable file, unknown or repeated columns, non-numbers or
        starts outside the arena, naming the file, row (1-based line number) and field.
    """
    from behavior_hmm.errors import DatasetError

    file = str(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.DictReader(fh)
            fields = [f.strip() for f in (reader.fieldnames or [])]
            allowed = {"angle", "distance", "goal_angle", "goal_distance"}
            if not fields:
                raise DatasetError(
                    "empty starts file (expected columns angle and/or distance)", file=file
                )
            repeated = [f for i, f in enumerate(fields) if f in fields[:i]]
            if repeated:
                raise DatasetError(
                    "column given twice (each of angle, distance, goal_<channel> at most once)",
                    file=file,
                    field=repeated[0],
                )
            unknown = [f for f in fields if f not in allowed]
            if unknown:
                close = difflib.get_close_matches(unknown[0], sorted(allowed), n=1)
                hint = f"; did you mean '{close[0]}'?" if close else ""
                raise DatasetError(
                    "unknown column (expected angle, distance, goal_angle, goal_distance)" + hint,
                    file=file,
                    field=unknown[0],
                )
            if "angle" not in fields and "distance" not in fields:
                raise DatasetError("a starts file needs a column angle and/or distance", file=file)
            starts: list[Start] = []
            for row in reader:
                line = reader.line_num  # the file's line number of this row
                start: Start = {}
                for key, raw in row.items():
                    if key is None:
                        raise DatasetError("more values than columns", file=file, row=line)
                    text = (raw or "").strip()
                    try:
                        value = float(text)
                    except ValueError:
                        raise DatasetError(
                            f"not a number: '{text}'", file=file, row=line, field=key.strip()
                        ) from None
                    if not np.isfinite(value):
                        raise DatasetError(
                            f"not a finite number: '{text}'", file=file, row=line, field=key.strip()
                        )
                    start[key.strip()] = value
                try:
                    check_start(start)
                except ConfigError as err:
                    raise DatasetError(str(err), file=file, row=line) from None
                starts.append(start)
    except OSError as err:
        raise DatasetError(f"cannot read starts file: {err.strerror}", file=file) from None
    except UnicodeDecodeError:
        raise DatasetError("not a UTF-8 text file", file=file) from None
    except csv.Error as err:  # e.g. a NUL byte or a cell beyond the csv module's limit
        raise DatasetError(f"not a readable CSV file ({err})", file=file) from None
    if not starts:
        raise DatasetError("no starts in file", file=file)
    return starts


def check_start(start: Start) -> None:
    """Raise ConfigError if a start (or its goal) lies outside the arena."""
    for key in ("distance", "goal_distance"):
        if key in start and not 0.0 <= start[key] <= ARENA_MAX_DISTANCE:
            raise ConfigError(
                f"start outside the arena: {key} {start[key]:g} m "
                f"not in [0, {ARENA_MAX_DISTANCE:g}]"
            )
    for key in ("angle", "goal_angle"):
        if key in start and not -180.0 <= start[key] <= 180.0:
            raise ConfigError(
                f"start outside the arena: {key} {start[key]:g} deg not in [-180, 180]"
            )


def _grid(lo: float, hi: float, step: float) -> list[float]:
    n = round((hi - lo) / step)
    return [round(lo + i * step, 6) for i in range(n + 1)]
