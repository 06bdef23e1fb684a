"""Default training grids (DESIGN §6) and the fixed test starts shipped with the package."""

from __future__ import annotations

import csv
import difflib
import io
from collections.abc import Sequence
from importlib import resources
from pathlib import Path

import numpy as np

from behavior_hmm._safe_read import MAX_SIDE_FILE_BYTES, read_text
from behavior_hmm.data import ARENA_MAX_DISTANCE
from behavior_hmm.errors import ConfigError
from behavior_hmm.teach._behaviors import Start, behavior_spec

#: Characters of a cell quoted in an error message (then ``...``).
_SHOWN_CHARS = 80


def _cell(text: str) -> str:
    """A cell for a one-line error message: a character that does not print (a line
    break inside a quoted cell) escaped as ``repr`` writes it, cut to ``_SHOWN_CHARS``."""
    shown = "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)
    return shown if len(shown) <= _SHOWN_CHARS else shown[:_SHOWN_CHARS] + "..."


def default_starts(behavior: str) -> list[Start]:
    """The default training grid of ``behavior`` (its spec's ``train_starts``, DESIGN §6)."""
    return [dict(s) for s in behavior_spec(behavior).train_starts()]


def test_starts(behavior: str) -> list[Start]:
    """The fixed test starts shipped in ``teach/starts/``, none on a training grid.

    15 per behavior; ``position`` has 30: 15 that need an approach, 15 a retreat.
    """
    shipped = behavior_spec(behavior).test_starts
    if callable(shipped):
        return [dict(s) for s in shipped()]
    if shipped is None:
        raise ConfigError(f"no test starts shipped for behavior '{behavior}'")
    ref = resources.files("behavior_hmm.teach").joinpath("starts", shipped)
    if not ref.is_file():
        raise ConfigError(f"no test starts shipped for behavior '{behavior}'")
    with resources.as_file(ref) as path:
        return read_starts(path)


def read_starts(
    path: str | Path,
    max_distance: float = ARENA_MAX_DISTANCE,
    channels: Sequence[str] | None = None,
    goals: Sequence[str] = (),
) -> list[Start]:
    """Read a starts CSV with columns ``angle`` and/or ``distance`` (and ``goal_<channel>``).

    ``max_distance`` (m): the farthest start allowed (our arena's by default; another
    robot's, ``--env``, may be larger). ``channels``: a robot's start channels (contract
    version 2, e.g. ``x, y``): the columns are then those and ``goal_<channel>``.
    ``goals``: more channels a row may give a goal on (``goal_<channel>``: a model's
    inputs, e.g. a grasp's ``goal_arm``).

    The file is read as every user file is (:func:`behavior_hmm._safe_read.read_text`):
    a regular file (a FIFO or a device is refused unopened) of UTF-8 text, at most 4 MiB,
    lines of at most 1 MiB.

    Raises
    ------
    DatasetError
        For a missing or unreadable file, unknown or repeated columns, non-numbers or
        starts outside the arena, naming the file, row (1-based line number) and field.
    """
    from behavior_hmm.errors import DatasetError

    file = str(path)
    text = read_text(path, limit=MAX_SIDE_FILE_BYTES, file=file)
    try:
        with io.StringIO(text, newline="") as fh:
            reader = csv.DictReader(fh)
            fields = [f.strip() for f in (reader.fieldnames or [])]
            names = ["angle", "distance"] if channels is None else list(channels)
            expected = " and/or ".join(names) if len(names) <= 2 else ", ".join(names)
            allowed = {*names, *(f"goal_{c}" for c in (*names, *goals))}
            if not fields:
                raise DatasetError(f"empty starts file (expected columns {expected})", file=file)
            repeated = [f for i, f in enumerate(fields) if f in fields[:i]]
            if repeated:
                raise DatasetError(
                    f"column given twice (each of {', '.join(names)}, goal_<channel> at most once)",
                    file=file,
                    field=_cell(repeated[0]),
                )
            unknown = [f for f in fields if f not in allowed]
            if unknown:
                close = difflib.get_close_matches(unknown[0], sorted(allowed), n=1)
                hint = f"; did you mean '{close[0]}'?" if close else ""
                raise DatasetError(
                    f"unknown column (expected {', '.join(sorted(allowed))})" + hint,
                    file=file,
                    field=_cell(unknown[0]),
                )
            if not any(c in fields for c in names):
                raise DatasetError(f"a starts file needs a column {expected}", file=file)
            starts: list[Start] = []
            for row in reader:
                line = reader.line_num  # the file's line number of this row
                start: Start = {}
                for key, raw in row.items():
                    if key is None:
                        raise DatasetError("more values than columns", file=file, row=line)
                    cell = (raw or "").strip()
                    try:
                        value = float(cell)
                    except ValueError:
                        raise DatasetError(
                            f"not a number: '{_cell(cell)}'", file=file, row=line, field=key.strip()
                        ) from None
                    if not np.isfinite(value):
                        raise DatasetError(
                            f"not a finite number: '{_cell(cell)}'",
                            file=file,
                            row=line,
                            field=key.strip(),
                        )
                    start[key.strip()] = value
                try:
                    check_start(start, max_distance)
                except ConfigError as err:
                    raise DatasetError(str(err), file=file, row=line) from None
                starts.append(start)
    except csv.Error as err:  # e.g. a cell beyond the csv module's limit
        reason = " ".join(str(err).split())[: 2 * _SHOWN_CHARS]
        raise DatasetError(f"not a readable CSV file ({reason})", file=file) from None
    if not starts:
        raise DatasetError("no starts in file", file=file)
    return starts


def check_start(start: Start, max_distance: float = ARENA_MAX_DISTANCE) -> None:
    """Raise ConfigError if a start (or its goal) lies outside the arena.

    ``max_distance`` (m) is our arena's by default; a robot of another size passes its own.
    """
    for key in ("distance", "goal_distance"):
        if key in start and not 0.0 <= start[key] <= max_distance:
            raise ConfigError(
                f"start outside the arena: {key} {start[key]:g} m not in [0, {max_distance:g}]"
            )
    for key in ("angle", "goal_angle"):
        if key in start and not -180.0 <= start[key] <= 180.0:
            raise ConfigError(
                f"start outside the arena: {key} {start[key]:g} deg not in [-180, 180]"
            )


def scaled_starts(starts: list[Start], env: object) -> list[Start]:
    """Starts scaled to a robot: ``start * env.unwrapped.start_scale + start_offset``.

    Our test starts are for a 7 cm robot in a 1.2 m arena; a robot of another size
    declares how to scale them (``start_scale``, e.g. ``{"distance": 5}``) and, if it
    cannot start touching the object at every bearing (its corners reach past its
    front), how far to keep off it (``start_offset``, e.g. ``{"distance": 0.1}``; starts
    only, not goals). See docs/robots.md. Without either they stay as they are.
    """
    base = getattr(env, "unwrapped", env)
    scale = getattr(base, "start_scale", None) or {}
    offset = getattr(base, "start_offset", None) or {}
    out = []
    for start in starts:
        row = dict(start)
        for key, factor in scale.items():
            for name in (key, f"goal_{key}"):
                if name in row:
                    row[name] = round(row[name] * float(factor), 6)
        for key, shift in offset.items():
            if key in row:
                row[key] = round(row[key] + float(shift), 6)
        out.append(row)
    return out
