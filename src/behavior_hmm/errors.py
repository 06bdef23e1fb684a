"""One error hierarchy for the whole package.

The command line turns every :class:`BehaviorHMMError` into a one-line message
and exit code 2; any other exception is a bug.
"""

from __future__ import annotations


class BehaviorHMMError(Exception):
    """Root of every error this package raises on purpose (user errors)."""


class ConfigError(BehaviorHMMError, ValueError):
    """A parameter, option or argument is out of its documented range."""


class DatasetError(BehaviorHMMError, ValueError):
    """A dataset (Parquet or CSV) is malformed; the message names where.

    Parameters
    ----------
    message
        What is wrong, e.g. ``"NaN value"``.
    file, episode, row, field
        Where it is wrong; each is optional and included in ``str(err)``.
    """

    def __init__(
        self,
        message: str,
        *,
        file: str | None = None,
        episode: int | str | None = None,
        row: int | None = None,
        field: str | None = None,
    ) -> None:
        self.file = file
        self.episode = episode
        self.row = row
        self.field = field
        self.reason = message
        where = []
        if file is not None:
            where.append(str(file))
        if episode is not None:
            where.append(f"episode {episode}")
        if row is not None:
            where.append(f"row {row}")
        if field is not None:
            where.append(f"field '{field}'")
        prefix = ", ".join(where)
        super().__init__(f"{prefix}: {message}" if prefix else message)


class ModelFileError(BehaviorHMMError, ValueError):
    """A model file is missing, corrupted, tampered with or of another version."""


class NotFittedError(BehaviorHMMError, AttributeError):
    """An estimator was used before ``fit``."""


class UnreachableGoalError(BehaviorHMMError):
    """No observation path leads from the current observation to the goal."""


class SimulationError(BehaviorHMMError, RuntimeError):
    """The physics became unstable (NaN/Inf) or the simulator was misused."""
