"""Automatic choice of an SBLM's input channels from the demonstrations (issue 30, item 2).

The thesis (7.2, tables 6.3/6.4) found by hand that angular velocity hurts the turn and
linear velocity the approach, and lists feature selection as future work.
:func:`select_inputs` picks the channels by greedy forward selection on a criterion
computed from the demonstrations alone (never from test starts or a simulator), so it also
works on channels a robot declares itself (eight proximity readings, of which only some
matter).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.data import CommandScaler, Dataset, SignalPipeline
from behavior_hmm.errors import ConfigError
from behavior_hmm.generators._features import command_features

FloatArray = NDArray[np.float64]

#: A channel joins the inputs only if it lowers the criterion by at least this share.
DEFAULT_MARGIN = 0.02
#: Neighbours of the k-nearest-neighbour regression that scores a subset.
DEFAULT_NEIGHBORS = 10
#: Folds of episodes (each held out once).
DEFAULT_FOLDS = 5
#: A channel whose held-out R² from the recent commands reaches this is an echo.
ECHO_R2 = 0.9
#: ... and the last command explains at least this share of its change per cycle.
ECHO_MOVED = 0.5
#: Lags (control cycles) of the recent commands that the echo test reads.
ECHO_LAGS = (1, 5, 10, 20)
#: A channel whose filtered readings span less than this share of its declared range
#: over the demonstrations is still: no sensor resolves it (1 %: the smallest sensor
#: noise of ``experiment faults`` is 0.5 % of the range per reading).
STILL_SHARE = 0.01
#: What :func:`select_inputs` does with echoes: ``"allow"`` (the criterion decides) or
#: ``"exclude"`` (left out before the selection).
ECHO_POLICIES = ("allow", "exclude")


@dataclass(frozen=True)
class InputChoice:
    """The outcome of :func:`select_inputs`.

    Attributes
    ----------
    inputs
        The chosen channels, in the order they were added.
    scores
        The criterion of every subset tried (``()``: the onset clock alone), keyed by the
        subset in the order its channels were added. Lower is better; 1 is no better than
        predicting the mean command.
    reason
        One paragraph saying which channels were picked and why (the criterion values).
    echoes
        Per candidate channel: the held-out R² of its value from the recent commands and
        the share of its change per cycle the last command explains (an echo: both high).
    """

    inputs: tuple[str, ...]
    scores: dict[tuple[str, ...], float] = field(default_factory=dict)
    reason: str = ""
    echoes: dict[str, tuple[float, float]] = field(default_factory=dict)

    def summary(self) -> str:
        """One line: the pick and the criterion along the greedy path."""
        path = [()] + [self.inputs[: k + 1] for k in range(len(self.inputs))]
        steps = " -> ".join(
            f"{{{','.join(s)}}} {self.scores[s]:.4g}" for s in path if s in self.scores
        )
        return f"inputs {','.join(self.inputs)} chosen automatically (held-out error {steps})"


def select_inputs(
    dataset: Dataset,
    *,
    max_inputs: int = 3,
    candidates: Sequence[str] | None = None,
    random_state: int = 0,
    margin: float = DEFAULT_MARGIN,
    n_neighbors: int = DEFAULT_NEIGHBORS,
    n_folds: int = DEFAULT_FOLDS,
    echoes: str = "allow",
    **sblm_params: Any,
) -> InputChoice:
    """Choose the SBLM's input channels from the demonstrations alone.

    Greedy forward selection: start from the goal's channels (none if the dataset
    states no goal), add the candidate that lowers the criterion most, stop when none
    lowers it by ``margin`` (relative, 2 %) or ``max_inputs`` are chosen. At least one
    channel is always chosen (the SBLM needs one).

    Criterion (and why), in two steps, from the demonstrations alone, corrective ones
    included (``collect --corrections``): they show what the teacher reacts to, so a
    channel that only a recovery moves (the approach's bearing) is seen to matter, even
    by a model that does not learn from them (``learn_corrections=False``):

    1. *What is read whatever the criterion says, and what is never read.*

       - The channels the dataset's goal is stated in (``metadata["goal"]``): a model
         that does not read them cannot tell that it has arrived.
       - Still channels are left out: readings that keep within ``STILL_SHARE`` (1 %) of
         their declared range over the demonstrations (the forward speed of a turn in
         place). No sensor resolves them, yet the
         nearest neighbours below would read their rounding residue, which follows the
         commands.
       - Echoes of the robot's own commands are found and named. A channel is an echo
         when the commands move it (the last command explains at least half of its
         change per cycle that its own last value leaves unexplained, ``ECHO_MOVED``)
         *and* its value is predicted by the last commands alone (held-out R² >= 0.9
         from the commands 1, 5, 10 and 20 cycles back, ``ECHO_R2``): the wheel-speed
         readings. Offline such a channel predicts the commands very well; in closed
         loop it feeds the generator's own output back (the copycat problem of
         imitation learning), which is what the thesis found by hand (tables 6.3/6.4:
         angular velocity hurt the turn, linear velocity the approach). With
         ``echoes="exclude"`` they are left out. The default, ``"allow"``, lets the
         criterion decide, because measured here they do not hurt: with the default
         preset's onset clock the criterion leaves them out of the turn by itself, and
         without the clock (the thesis preset) they carry the start-up motion the flat
         start window does not (docs/results.md, "Inputs chosen from the
         demonstrations"). Both conditions are needed: a reading the teacher reacts
         to is predicted by the commands too, but they do not move it (a proximity
         reading); a bearing is moved by them, but its value keeps where the robot
         started.
    2. *Greedy forward selection on a held-out error.* Each subset of the remaining
       channels is scored by the held-out squared error, over ``n_folds`` folds of whole
       demonstrations (folds drawn from ``random_state``), of a k-nearest-neighbour
       regression of the normalized commands on the SBLM's onset clock and the subset's
       readings, low-pass filtered and normalized exactly as the SBLM does
       (``cutoff_hz``, the channels' ranges), divided by the commands' variance. Nearest
       neighbours because the commands are nonlinear in the readings (ramps, braking,
       saturation) and an irrelevant channel dilutes the distances, so it *raises* the
       held-out error instead of being ignored as by a linear fit; held out by
       demonstration because rows of one demonstration are near-copies of each other
       (as the generators' early stopping holds out whole demonstrations,
       ``generator_test_fraction``), so it measures generalization to new starts.

    The proxy stands in for the held-out error of the SBLM's own generators, which needs
    the CobARTs and the Behavior-HMM of every subset (seconds per subset; the proxy, a
    fraction of a second): the default turn and approach grids take 2-3 s each on two
    cores.

    Parameters
    ----------
    dataset
        Demonstrations of one behavior.
    max_inputs
        Most channels to choose.
    candidates
        Channels to choose from (default: all of the dataset's sensor channels).
    random_state
        Seed of the folds (the only random choice; the regression is deterministic).
    margin
        Least relative decrease of the criterion for a channel to join.
    n_neighbors, n_folds
        The regression's neighbours and the number of folds of episodes.
    echoes
        ``"allow"`` (echoes are candidates like the rest) or ``"exclude"``.
    **sblm_params
        SBLM parameters; ``cutoff_hz`` and ``onset_clock`` shape the features.

    Returns
    -------
    InputChoice
    """
    from sklearn.neighbors import KNeighborsRegressor

    from behavior_hmm.models._sblm import SBLM

    if not isinstance(dataset, Dataset):
        raise ConfigError(f"select_inputs expects a behavior_hmm.data.Dataset, got {type(dataset)}")
    names = tuple(dataset.sensor_channels if candidates is None else candidates)
    if not names:
        raise ConfigError("select_inputs needs at least one candidate channel")
    unknown = [c for c in names if c not in dataset.sensor_channels]
    if unknown:
        raise ConfigError(
            f"candidate channels not in the dataset: {', '.join(unknown)} "
            f"(it has {', '.join(dataset.sensor_channels)})"
        )
    if len(set(names)) != len(names):
        raise ConfigError(f"candidate channels repeat: {names}")
    if isinstance(max_inputs, bool) or not isinstance(max_inputs, int) or max_inputs < 1:
        raise ConfigError(f"max_inputs must be an integer >= 1, got {max_inputs!r}")
    if not 0 <= margin < 1:
        raise ConfigError(f"margin must lie in [0, 1), got {margin!r}")
    if echoes not in ECHO_POLICIES:
        raise ConfigError(f"echoes must be one of {', '.join(ECHO_POLICIES)}, got {echoes!r}")
    params = SBLM(inputs=names[:1], **sblm_params)  # its defaults and checks
    params.check_params()

    # every demonstration, corrective ones included: they show what the teacher reacts to
    ds = dataset
    if len(ds) < 2:
        raise ConfigError("select_inputs needs at least two demonstrations to hold one out")
    lengths = ds.lengths
    pipeline = SignalPipeline.for_dataset(ds, names, params.cutoff_hz)
    x = pipeline.transform(ds)  # normalized by each channel's declared range, as the SBLM
    units = [spec.unit for spec in ds.command_specs]
    y = np.clip(CommandScaler(units).fit(ds.commands).transform(ds.commands), -1.0, 1.0)
    n_commands = y.shape[1]
    history = np.hstack([command_features(y, lengths, lag) for lag in ECHO_LAGS])
    base = []
    clock = int(params.onset_clock)
    if clock > 0:
        steps = np.concatenate([np.arange(n) for n in lengths])
        base.append((np.minimum(steps, clock) / clock)[:, None])
    base_x = np.hstack(base) if base else np.zeros((len(y), 1))

    rng = np.random.default_rng(random_state)
    k_folds = min(int(n_folds), len(ds))
    fold = np.repeat(rng.permutation(len(ds)) % k_folds, lengths)

    def held_out(feats: FloatArray, target: FloatArray) -> float:
        """Held-out squared error over the folds / the target's variance."""
        total = float(np.sum((target - target.mean(axis=0)) ** 2))
        if total <= 0.0:
            return 0.0
        sse = 0.0
        for f in range(k_folds):
            test = fold == f
            reg = KNeighborsRegressor(n_neighbors=min(n_neighbors, int((~test).sum())))
            reg.fit(feats[~test], target[~test])
            sse += float(np.sum((reg.predict(feats[test]) - target[test]) ** 2))
        return sse / total

    # Echoes (e.g. wheel speeds): channels the commands move (their change per cycle is
    # predicted far better knowing the last command) *and* whose value the recent commands
    # alone predict. A reading the teacher reacts to is predicted by the commands too,
    # but the commands do not move it; a bearing is moved by them, but its value keeps
    # where the robot started.
    raw = SignalPipeline.for_dataset(ds, names, None).transform(ds)
    raw_prev = _previous(raw, lengths)
    change = raw - raw_prev
    echo_r2: dict[str, float] = {}
    moved: dict[str, float] = {}
    for j, c in enumerate(names):
        echo_r2[c] = 1.0 - held_out(history, x[:, [j]])
        own = held_out(raw_prev[:, [j]], change[:, [j]])
        both = held_out(np.hstack([raw_prev[:, [j]], history[:, :n_commands]]), change[:, [j]])
        moved[c] = 0.0 if own <= 1e-12 else max(0.0, 1.0 - both / own)
    echo_names = tuple(c for c in names if echo_r2[c] >= ECHO_R2 and moved[c] >= ECHO_MOVED)
    # The goal's channels are read whatever the criterion says: a model that does not
    # read them cannot tell that it has arrived.
    goal = dataset.metadata.get("goal")
    required = tuple(c for c in names if isinstance(goal, Mapping) and c in goal)
    # Still channels (a reading that keeps within 1 % of its range, e.g. the forward speed
    # of a turn in place) carry no information a sensor could resolve; the nearest
    # neighbours would read their rounding residue, which follows the commands.
    spread = np.ptp(x, axis=0) / 2.0  # x is normalized onto [-1, 1]
    still = tuple(c for j, c in enumerate(names) if spread[j] < STILL_SHARE and c not in required)
    left_out = still + (echo_names if echoes == "exclude" else ())
    pool = tuple(c for c in names if c not in left_out)
    all_out = len(pool) == len(required)
    if all_out and not required:  # nothing else to read: choose among them all the same
        pool = names

    def score(subset: tuple[str, ...]) -> float:
        cols = [names.index(c) for c in subset]
        return held_out(np.hstack([base_x, x[:, cols]]), y)

    scores: dict[tuple[str, ...], float] = {(): score(())}
    chosen: tuple[str, ...] = required
    if chosen:
        scores[chosen] = score(chosen)
    stop_note = ""
    while len(chosen) < min(max(max_inputs, len(required)), len(pool)):
        tried = {c: score((*chosen, c)) for c in pool if c not in chosen}
        for c, value in tried.items():
            scores[(*chosen, c)] = value
        best = min(tried, key=lambda c: (tried[c], names.index(c)))
        now = scores[chosen]
        if tried[best] > now * (1.0 - margin) and chosen:
            stop_note = (
                f"; no further channel lowered it by {margin:.0%} (best, {best}: {tried[best]:.4g})"
            )
            break
        if tried[best] > now * (1.0 - margin):
            stop_note = f"; no channel lowered it by {margin:.0%}, so the best one is kept"
        chosen = (*chosen, best)
    else:
        stop_note = f"; stopped at max_inputs={max_inputs}" if len(chosen) < len(pool) else ""
    path_steps: list[tuple[str, ...]] = [(), required] + [
        chosen[:k] for k in range(len(required) + 1, len(chosen) + 1)
    ]
    path = " -> ".join(
        f"{{{','.join(t)}}} {scores[t]:.4g}" for t in dict.fromkeys(path_steps) if t in scores
    )
    notes = []
    if required:
        which = "channel" if len(required) == 1 else "channels"
        notes.append(f"{', '.join(required)} read first (the goal's {which})")
    if still:
        notes.append(
            f"{', '.join(still)} left out as still (within {STILL_SHARE:.0%} of the range)"
        )
    if echo_names:
        what = "left out" if echoes == "exclude" else "candidates like the rest"
        notes.append(
            f"echoes of the robot's own commands, {what} (moved by them and predicted by "
            "the last commands: "
            + ", ".join(f"{c} R² {echo_r2[c]:.2f}, change {moved[c]:.0%}" for c in echo_names)
            + ")"
        )
    if all_out and not required:
        notes.append("every channel was left out, so all are candidates all the same")
    reason = (
        f"Chose {','.join(chosen)} from {','.join(names)}: "
        + "".join(f"{n}; " for n in notes)
        + f"greedy forward selection on the held-out error (over {k_folds} folds of whole "
        f"demonstrations) of a {n_neighbors}-nearest-neighbour prediction of the commands "
        f"from the onset clock and the channels: {path}{stop_note}."
    )
    return InputChoice(
        inputs=chosen,
        scores=scores,
        reason=reason,
        echoes={c: (echo_r2[c], moved[c]) for c in names},
    )


def _previous(a: FloatArray, lengths: NDArray[np.int64]) -> FloatArray:
    """Each row's previous row in its episode (an episode's first row: itself)."""
    out = np.empty_like(a)
    start = 0
    for n in lengths:
        stop = start + int(n)
        out[start] = a[start]
        out[start + 1 : stop] = a[start : stop - 1]
        start = stop
    return out
