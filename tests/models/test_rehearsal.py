"""Rehearsal rows (issue 29): an SBLM keeps a bounded sample of its generators' training
rows, and an update fine-tunes a network on them beside the new rows."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from behavior_hmm.data import Dataset
from behavior_hmm.errors import ConfigError, ModelFileError
from behavior_hmm.models import SBLM
from behavior_hmm.models import _modelfile as mf
from behavior_hmm.models._rehearsal import (
    DEFAULT_REHEARSAL,
    RehearsalRows,
    merged,
    rehearsal_rng,
    sample,
)
from behavior_hmm.teach import collect

#: Starts between those of ``turn_data`` (every 20 deg from -170).
NEW_STARTS = [{"angle": float(a), "distance": 0.5} for a in (-155, -95, -35, 25, 85, 145)]


def _candidates(
    n_per: tuple[int, ...], run: int = 5
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Rows of primitives 0, 1, ...: ``n_per[p]`` each, in runs of ``run`` rows, one
    demonstration per 10 rows; feature 0 is the row number."""
    prims = np.concatenate([np.full(n, p) for p, n in enumerate(n_per)]).astype(np.int64)
    n = prims.size
    features = np.stack([np.arange(n, dtype=np.float64), np.ones(n)], axis=1)
    targets = np.zeros((n, 2))
    groups = np.arange(n) // 10
    segments = np.arange(n) // run
    return features, targets, prims, groups, segments


def _sample(
    cap: int, n_per: tuple[int, ...], *, by_segment: bool = False, seed: int = 0
) -> RehearsalRows:
    f, t, p, g, s = _candidates(n_per)
    seen = np.bincount(p, minlength=len(n_per)).astype(np.int64)
    return sample(
        f,
        t,
        p,
        g,
        s,
        np.ones(p.size),
        seen,
        cap=cap,
        by_segment=by_segment,
        rng=rehearsal_rng(seed, 0),
    )


def test_a_sample_keeps_at_most_cap_rows_of_each_primitive_and_all_of_a_small_one() -> None:
    rows = _sample(40, (300, 25, 90))
    kept = np.bincount(rows.primitives, minlength=3)
    np.testing.assert_array_equal(kept, [40, 25, 40])
    # a primitive with fewer rows than the cap keeps every one of them, unchanged
    f, *_ = _candidates((300, 25, 90))
    np.testing.assert_array_equal(
        rows.features[rows.primitives == 1], f[300:325].astype(np.float32)
    )
    np.testing.assert_array_equal(rows.seen, [300, 25, 90])
    # demonstrations and runs renumbered from 0 in order
    assert rows.groups.min() == 0 and rows.segments.min() == 0
    assert set(np.diff(np.unique(rows.groups))) == {1}
    # drawn at random over the whole primitive, not its first rows
    first = rows.features[rows.primitives == 0, 0]
    assert first.max() > 200 and first.min() < 100
    same = _sample(40, (300, 25, 90))
    assert same.features.tobytes() == rows.features.tobytes()
    other = _sample(40, (300, 25, 90), seed=1)
    assert other.features.tobytes() != rows.features.tobytes()


def test_recurrent_generators_keep_whole_runs() -> None:
    rows = _sample(23, (300,), by_segment=True)
    assert rows.n_rows == 20  # four whole runs of 5: a fifth would pass the cap
    runs = rows.features[:, 0] // 5
    for run in np.unique(runs):
        np.testing.assert_array_equal(
            np.sort(rows.features[runs == run, 0]), np.arange(5) + run * 5
        )


def test_a_run_that_does_not_fit_is_passed_over_not_the_rest() -> None:
    """Runs of 400, 300, 50, 50 and 600 rows at a cap of 512: whatever the draw, the runs
    that still fit after the first are kept (at least 400 rows, never past the cap)."""
    lengths = [400, 300, 50, 50, 600]
    segments = np.repeat(np.arange(5), lengths)
    n = segments.size
    for seed in range(20):
        rows = sample(
            np.zeros((n, 1)),
            np.zeros((n, 1)),
            np.zeros(n, dtype=np.int64),
            np.zeros(n, dtype=np.int64),
            segments,
            np.ones(n),
            np.array([n]),
            cap=512,
            by_segment=True,
            rng=rehearsal_rng(seed, 0),
        )
        assert 400 <= rows.n_rows <= 512, (seed, rows.n_rows)


def test_a_kept_row_stands_for_the_rows_it_was_drawn_from() -> None:
    """100 kept rows standing for 10,000 against 100 new rows: the next sample of 100
    holds about 99 % old rows (not half)."""
    f, t, p, g, s = _candidates((200,))
    weights = np.r_[np.full(100, 100.0), np.ones(100)]
    rows = sample(
        f,
        t,
        p,
        g,
        s,
        weights,
        np.array([10_100]),
        cap=100,
        by_segment=False,
        rng=rehearsal_rng(3, 1),
    )
    old = int(np.count_nonzero(rows.features[:, 0] < 100))
    assert old >= 90, old
    even = sample(
        f,
        t,
        p,
        g,
        s,
        np.ones(200),
        np.array([200]),
        cap=100,
        by_segment=False,
        rng=rehearsal_rng(3, 1),
    )
    assert 30 <= int(np.count_nonzero(even.features[:, 0] < 100)) <= 70


def test_merged_rows_number_their_demonstrations_and_runs_apart() -> None:
    a, b = _sample(10, (50, 0)), _sample(10, (0, 50), seed=2)
    both = merged(a, b)
    assert both.n_rows == 20
    assert not set(both.groups[:10]) & set(both.groups[10:])
    assert not set(both.segments[:10]) & set(both.segments[10:])
    np.testing.assert_array_equal(both.seen, b.seen)


def test_fit_keeps_rows_and_is_otherwise_unchanged(turn_data: Dataset, turn_model: SBLM) -> None:
    assert turn_model.rehearsal == DEFAULT_REHEARSAL and turn_model.rehearsal_ is not None
    small = SBLM(inputs=("angle",), epochs=60, random_state=0, rehearsal=64).fit(turn_data)
    rows = small.rehearsal_
    assert rows is not None
    gens = small.generators_
    kept = np.bincount(rows.primitives, minlength=gens.n_primitives_)
    assert kept.max() == 64
    # every primitive's originals counted (half its training rows: the rest are noise copies)
    np.testing.assert_array_equal(2 * rows.seen, gens.n_train_ + gens.n_test_)
    np.testing.assert_array_equal(kept, np.minimum(rows.seen, 64))
    assert rows.features.shape[1] == gens.n_features_in_
    # a primitive with no more rows than the cap keeps them all, in order, at any cap
    whole = rows.seen <= 64
    big = turn_model.rehearsal_
    for p in np.flatnonzero(whole):
        mine, theirs = rows.features[rows.primitives == p], big.features[big.primitives == p]
        assert mine.tobytes() == theirs.tobytes(), p
    # fitting is the same with any cap, or none
    none = SBLM(inputs=("angle",), epochs=60, random_state=0, rehearsal=0).fit(turn_data)
    assert none.rehearsal_ is None
    for model in (none, small):
        for a, b in zip(model.generators_.coefs_, turn_model.generators_.coefs_, strict=True):
            assert a.tobytes() == b.tobytes()


def _model_bytes_without(path: Path, drop: str | None = None, **replace: np.ndarray) -> bytes:
    """The model file with one array dropped or replaced (and signed again)."""
    header, arrays = mf.loads(path.read_bytes(), str(path))
    if drop:
        del arrays[drop]
    arrays.update(replace)
    return mf.dumps(header["kind"], header["params"], header["state"], arrays)


def test_kept_rows_save_load_and_hostile_ones_are_refused(turn_model: SBLM, tmp_path: Path) -> None:
    path = tmp_path / "m.bhmm"
    turn_model.save(path)
    loaded = SBLM.load(path)
    rows, back = turn_model.rehearsal_, loaded.rehearsal_
    assert rows is not None and back is not None
    for name in ("features", "targets", "primitives", "groups", "segments", "seen"):
        assert getattr(rows, name).tobytes() == getattr(back, name).tobytes(), name
    index = rows.to_arrays()["index"]
    n_prim = turn_model.generators_.n_primitives_
    bad = {
        "lacks array": {"drop": "rehearsal.targets"},
        "names a primitive": {"rehearsal.index": np.c_[index[:, :1] * 0 + n_prim, index[:, 1:]]},
        f"more than rehearsal={turn_model.rehearsal}": {
            "rehearsal.index": np.c_[index[:, :1] * 0, index[:, 1:]]
        },
        "counts fewer rows": {"rehearsal.seen": rows.seen * 0},
        "one count per primitive": {"rehearsal.seen": rows.seen[:-1]},
        "inputs and outputs": {"rehearsal.features": rows.features[:, :-1]},
        "beyond": {"rehearsal.targets": rows.targets + 1e7},
        "past its rows": {"rehearsal.index": np.c_[index[:, :2], index[:, 2:] + 10**6]},
        "splits or mixes": {"rehearsal.index": np.c_[index[:, :2], index[::-1, 2:]]},
        "outside": {"rehearsal.targets": rows.targets * 0 + 1.5},
        "or more than": {"rehearsal.seen": rows.seen + 2**50},
    }
    for message, change in bad.items():
        drop = change.pop("drop", None)
        hostile = tmp_path / "h.bhmm"
        hostile.write_bytes(_model_bytes_without(path, drop, **change))  # type: ignore[arg-type]
        with pytest.raises(ModelFileError, match=message):
            SBLM.load(hostile)


@pytest.fixture(scope="module")
def grown(turn_model: SBLM, tmp_path_factory: pytest.TempPathFactory) -> tuple[SBLM, SBLM, SBLM]:
    """(before, grown with its kept rows, grown without them) on new demonstrations."""
    new = collect("turn", NEW_STARTS, sim="kinematic", seed=7, noise=0.01)
    folder = tmp_path_factory.mktemp("rehearsal")
    turn_model.save(folder / "m.bhmm")
    before, after, bare = (SBLM.load(folder / "m.bhmm") for _ in range(3))
    after.partial_fit(new)
    bare.rehearsal_ = None  # a model file written before rows were kept
    bare.partial_fit(new)
    return before, after, bare


def test_an_update_rehearses_the_kept_rows_and_redraws_only_theirs(
    grown: tuple[SBLM, SBLM, SBLM],
) -> None:
    before, after, bare = grown
    old, rows = before.rehearsal_, after.rehearsal_
    assert old is not None and rows is not None and bare.rehearsal_ is None
    record = after.updates_[-1]
    tuned = np.array(record["fine_tuned"])
    assert record["rehearsed"] == old.of(tuned).n_rows > 0
    assert bare.updates_[-1]["rehearsed"] == 0
    gens, bare_gens = after.generators_, bare.generators_
    # a fine-tuned network trained on its kept rows as well as (twice, with the noise
    # copies) its new ones
    for p in tuned:
        extra = 2 * int(np.count_nonzero(old.primitives == p))
        assert (
            gens.n_train_[p] + gens.n_test_[p]
            == bare_gens.n_train_[p] + bare_gens.n_test_[p] + extra
        )
    # the rows of the primitives without new rows stay bit for bit
    visited = np.unique(after.primitives_.labels_)
    untouched = [p for p in range(old.seen.size) if p not in visited]
    assert untouched
    for p in untouched:
        a, b = old.features[old.primitives == p], rows.features[rows.primitives == p]
        assert a.tobytes() == b.tobytes(), p
    assert np.bincount(rows.primitives).max() <= after.rehearsal
    n_new = rows.seen[: old.seen.size] - old.seen
    assert (n_new[untouched] == 0).all() and (n_new[tuned] > 0).all()


def test_rehearsal_keeps_what_a_network_learned_on_the_old_rows(
    grown: tuple[SBLM, SBLM, SBLM],
) -> None:
    """A fine-tuned network's error on the old rows: near its error before the update
    with the kept rows, far above it without them (forgetting)."""
    before, after, bare = grown
    old = before.rehearsal_
    assert old is not None
    errors = {}
    for name, model in (("before", before), ("after", after), ("bare", bare)):
        total = 0.0
        for p in after.updates_[-1]["fine_tuned"]:
            mine = old.primitives == p
            out = model.generators_.predict(
                old.features[mine].astype(np.float64), np.full(mine.sum(), p)
            )
            total += float(np.sum((out - old.targets[mine]) ** 2))
        errors[name] = total
    assert errors["after"] < errors["bare"], errors
    assert errors["after"] < 2.0 * errors["before"], errors


def test_a_recurrent_sblm_keeps_whole_runs_and_rehearses_them(turn_data: Dataset) -> None:
    model = SBLM(
        inputs=("angle",), generator_network="elman", hidden=5, epochs=3, rehearsal=64
    ).fit(turn_data)
    rows = model.rehearsal_
    assert rows is not None
    assert np.bincount(rows.primitives).max() <= 64
    # each kept run is whole: consecutive rows of one primitive and one demonstration,
    # stored together, its onset clock (the last feature) one cycle apart row to row
    # (until it tops out at 1), where single rows drawn at random would skip cycles
    tick = 1.0 / model.onset_clock
    for run in np.unique(rows.segments):
        mine = np.flatnonzero(rows.segments == run)
        np.testing.assert_array_equal(mine, np.arange(mine[0], mine[-1] + 1))
        assert np.unique(rows.primitives[mine]).size == 1
        assert np.unique(rows.groups[mine]).size == 1
        steps = np.diff(rows.features[mine, -1].astype(np.float64))
        assert (np.isclose(steps, tick, atol=1e-6) | np.isclose(steps, 0.0)).all(), steps
    model.partial_fit(collect("turn", NEW_STARTS[:2], sim="kinematic", seed=7))
    assert model.updates_[-1]["rehearsed"] > 0


def test_a_lowered_rehearsal_is_refused_and_zero_drops_the_rows(
    turn_model: SBLM, tmp_path: Path
) -> None:
    """A file never holds more rows a primitive than its ``rehearsal`` says."""
    path = tmp_path / "m.bhmm"
    turn_model.save(path)
    new = collect("turn", NEW_STARTS[:2], sim="kinematic", seed=7)
    low = SBLM.load(path).set_params(rehearsal=8)
    with pytest.raises(ConfigError, match="rehearsal=8 is below"):
        low.partial_fit(new)
    with pytest.raises(ConfigError, match="rehearsal=8 is below"):
        low.save(tmp_path / "low.bhmm")
    assert not (tmp_path / "low.bhmm").exists()
    none = SBLM.load(path).set_params(rehearsal=0)
    none.partial_fit(new)
    assert none.updates_[-1]["rehearsed"] == 0 and none.rehearsal_ is None
    none.save(tmp_path / "none.bhmm")
    assert SBLM.load(tmp_path / "none.bhmm").rehearsal_ is None
