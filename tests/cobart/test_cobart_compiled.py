"""The compiled CobART kernels and the exact winner rule they share with the numpy paths."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from cobart_testing import assert_same_bits as _same
from cobart_testing import episodes, params, turn_dataset
from hypothesis import HealthCheck, assume, given, settings

from behavior_hmm.cobart import CobART, _live
from behavior_hmm.cobart import _compiled as compiled
from behavior_hmm.cobart._exact import Groups, exact_mismatch, refine


@pytest.fixture
def both() -> Iterator[None]:
    """Skip without numba; leave the kernel setting as it was."""
    pytest.importorskip("numba", reason="numba is not installed (the 'fast' extra)")
    previous = compiled.set_kernel("auto")
    yield
    compiled.set_kernel(previous)


def _run(kernel: str, x: np.ndarray, lengths: list[int], kw: dict[str, Any]) -> tuple[Any, ...]:
    compiled.set_kernel(kernel)  # type: ignore[arg-type]
    assert compiled.cobart_kernel() == kernel
    model = CobART(**kw).fit(x, lengths)
    half = len(lengths) // 2
    if half:  # continue from the categories learned so far
        split = sum(lengths[:half])
        model = CobART(**kw).fit(x[:split], lengths[:half]).partial_fit(x[split:], lengths[half:])
    cat = model.categorize(x, lengths)
    return model.labels_, model.prototypes_, model.counts_, cat.labels, cat.scores


@pytest.mark.usefixtures("both")
@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=episodes(max_channels=3, max_episodes=4, max_len=40), kw=params)
def test_kernels_learn_and_categorize_as_the_numpy_paths(
    data: tuple[np.ndarray, list[int]], kw: dict[str, Any]
) -> None:
    x, lengths = data
    _same(_run("numpy", x, lengths, kw), _run("numba", x, lengths, kw))


@pytest.mark.usefixtures("both")
def test_kernels_rebuild_grow_and_match_on_many_categories(monkeypatch: pytest.MonkeyPatch) -> None:
    # small leaves, a short tail and frequent rebuilds: every driver path runs many times
    monkeypatch.setattr(compiled, "LEAF_SIZE", 4)
    monkeypatch.setattr(compiled, "TAIL_MAX", 3)
    monkeypatch.setattr(compiled, "REBUILD_ROWS", 17)
    x, lengths = turn_dataset(two_channels=True)
    kw = {"rho": 0.995, "window": 5}
    numpy_run = _run("numpy", x, lengths, kw)
    numba_run = _run("numba", x, lengths, kw)
    assert numpy_run[1].shape[0] > 100  # capacity grown from 32 more than once
    _same(numpy_run, numba_run)


@pytest.mark.usefixtures("both")
@pytest.mark.parametrize("search", ["numpy", "compiled"])
def test_live_stream_equals_the_compiled_categorize(
    search: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    x, lengths = turn_dataset(two_channels=True)
    compiled.set_kernel("numba")
    model = CobART(rho=0.99, window=4).fit(x, lengths)
    cat = model.categorize(x, lengths)
    # reading by reading: screening every category (numpy) or searching the tree
    monkeypatch.setattr(_live, "LIVE_COMPILED_MIN", 1 if search == "compiled" else 10**9)
    stream = model.stream()
    assert (stream._search is not None) == (search == "compiled")
    compiled.set_kernel("numpy")
    screened = model.stream()  # every category's screened mismatch, fresh each update
    start = 0
    for n in lengths:
        stream.reset()
        screened.reset()
        for t in range(start, start + n):
            k, novel, score = stream.update(x[t])
            assert (k, score) == (cat.labels[t], cat.scores[t])
            assert novel == cat.novel[t]
            screened.update(x[t])
            if t % 7 == 0:  # the property scores every category when the update did not
                assert stream.mismatch.tobytes() == screened.mismatch.tobytes()
        start += n


def test_kernel_setting_is_checked() -> None:
    with pytest.raises(ValueError, match="unknown CobART kernel"):
        compiled.set_kernel("fortran")  # type: ignore[arg-type]


def _groups() -> Groups:
    gs = np.zeros((5, 2))
    gs[:3, 0] = 0.5
    gs[3:, 1] = 2.0
    return Groups.of(gs, np.array([0.6, 0.4]))


def test_refine_takes_the_exact_winner_over_the_screen() -> None:
    groups = _groups()
    p = np.array([0.1, 0.2, 0.3, 0.4, 0.5])
    z = np.array([[0.1, 0.2, 0.3, 0.4, 0.5 + 2e-9], [0.1, 0.2, 0.3, 0.4, 0.5 + 1e-9]])
    exact = [exact_mismatch(row, p, groups) for row in z]
    assert exact[1] < exact[0]
    # a screen whose rounding put category 0 first, within its margin
    v = np.array([exact[0] - 1e-9, exact[1]])
    assert refine(v, 0, 1e-9, z, p, groups) == (1, exact[1])
    # outside twice the margin the screen's winner stands without a second look
    assert refine(v, 0, 1e-12, z, p, groups)[0] == 0


def test_refine_breaks_exact_ties_to_the_lowest_category() -> None:
    groups = _groups()
    p = np.zeros(5)
    z = np.array([[0.3, 0.0, 0.0, 0.0, 0.0], [0.0, 0.3, 0.0, 0.0, 0.0]])
    v = np.array([0.1, 0.1 - 1e-15])
    ids = np.array([7, 3])
    assert refine(v, 1, 1e-12, z, p, groups, ids)[0] == 3
    assert refine(v, 1, 1e-12, z, p, groups, ids[::-1].copy())[0] == 3


def test_groups_refuse_mixed_scales() -> None:
    gs = np.zeros((2, 1))
    gs[:, 0] = [1.0, 2.0]
    with pytest.raises(ValueError, match="one scale"):
        Groups.of(gs, np.array([1.0]))


@settings(max_examples=200, deadline=None)
@given(data=episodes(max_channels=3, max_episodes=1, max_len=40))
def test_a_leafs_bound_never_exceeds_a_member_mismatch(data: tuple[np.ndarray, list[int]]) -> None:
    # the plain Python bodies of the kernels, run uncompiled
    x, _ = data
    assume(x.shape[0] >= 2)
    z = np.ascontiguousarray(x[:-1])
    p = np.ascontiguousarray(x[-1]) * 1.5
    f = z.shape[1]
    gs = np.zeros((f, f))
    gs[np.arange(f), np.arange(f)] = np.linspace(0.5, 40.0, f)
    groups = Groups.of(gs, np.full(f, 1.0 / f))
    gscale, gw = np.asarray(groups.scales), np.asarray(groups.weights)
    lo, hi = z.min(axis=0, keepdims=True), z.max(axis=0, keepdims=True)
    bound = compiled._lower_bound(p, lo, hi, 0, groups.index, groups.pointer, gscale, gw)
    for k in range(z.shape[0]):
        r = compiled._mismatch(z, k, p, groups.index, groups.pointer, gscale, gw, np.inf)
        assert bound <= r
        assert r == exact_mismatch(z[k], p, groups)


@pytest.mark.parametrize("kernel", ["numpy", "numba"])
def test_an_exact_tie_goes_to_the_lowest_category(kernel: str, both: None) -> None:
    # categories at +0.5 (0) and -0.5 (1), which never move (d = 0); 0.0 lies as far
    # from both, so it resonates with the first, also after a step that won category 1
    x = np.r_[np.full(4, 0.5), np.full(4, -0.5), np.full(3, -0.5), np.zeros(4)][:, None]
    lengths = [4, 4, 7]
    compiled.set_kernel(kernel)  # type: ignore[arg-type]
    model = CobART(rho=0.4, window=1, a=1.0, d=0.0).fit(x, lengths)
    assert model.n_categories_ == 2
    np.testing.assert_array_equal(model.labels_, [0] * 4 + [1] * 7 + [0] * 4)
    np.testing.assert_array_equal(model.predict(x, lengths), model.labels_)


def test_a_small_live_stream_never_loads_the_kernels(monkeypatch: pytest.MonkeyPatch) -> None:
    # a live update runs inside a control cycle: importing numba there would stall it
    x, lengths = turn_dataset()
    model = CobART(rho=0.95, window=3).fit(x, lengths)
    assert model.n_categories_ < _live.LIVE_COMPILED_MIN
    loaded: list[bool] = []
    monkeypatch.setattr(compiled, "kernels", lambda: loaded.append(True))
    stream = model.stream()
    for reading in x[:50]:
        stream.update(reading)
    assert loaded == []
    model.categorize(x, lengths)  # offline, the switch is asked
    assert loaded


@pytest.mark.usefixtures("both")
def test_a_searching_live_stream_loads_and_compiles_before_its_first_update(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    x, lengths = turn_dataset()
    model = CobART(rho=0.95, window=3).fit(x, lengths)
    monkeypatch.setattr(_live, "LIVE_COMPILED_MIN", 1)
    asked: list[bool] = []
    real = compiled.kernels
    monkeypatch.setattr(compiled, "kernels", lambda: asked.append(True) or real())
    calls: list[tuple[Any, ...]] = []
    stream = model.stream()  # loads numba and compiles the search: outside any cycle
    assert asked and stream._search is not None
    search = stream._search
    best = search._best
    monkeypatch.setattr(search, "_best", lambda *a: calls.append(a) or best(*a))
    asked.clear()
    for reading in x[:50]:
        stream.update(reading)
    assert asked == [] and len(calls) == 50  # every update searched, none loaded anything


def _in_a_fresh_process(code: str) -> None:
    """Run ``code`` in a new interpreter (nothing compiled or imported yet); its asserts
    must hold."""
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


@pytest.mark.usefixtures("both")
def test_warm_compiles_every_kernel_before_any_fit() -> None:
    _in_a_fresh_process(
        "from behavior_hmm.cobart import _compiled as c; k = c.kernels();"
        "made = lambda: [bool(f.signatures) for f in k];"
        "assert not any(made()), 'compiled already';"
        "c.warm(); assert all(made()), 'not compiled';"
        "c.set_kernel('numpy'); c.warm()"
    )


#: The kernels' plain Python bodies, run uncompiled (slow, but every line is Python's).
_PLAIN = compiled.Kernels(
    learn=compiled.learn, predict=compiled.predict, build=compiled.build, best=compiled._best
)


def _boxes_hold_their_categories(tr: compiled.Tree, z: np.ndarray) -> None:
    leaves = np.flatnonzero(tr.start >= 0)
    for node in range(tr.skip.shape[0]):
        under = leaves[(leaves >= node) & (leaves < tr.skip[node])]
        members = np.concatenate([tr.perm[tr.start[i] : tr.end[i]] for i in under])
        assert np.all(z[members] >= tr.lo[node]) and np.all(z[members] <= tr.hi[node])
        if tr.parent[node] >= 0:  # a subtree lies inside its parent's
            assert tr.parent[node] < node < tr.skip[node] <= tr.skip[tr.parent[node]]


@pytest.mark.parametrize("n", [0, 1, 8, 9, 57])
def test_the_tree_holds_every_category_once_in_boxed_leaves(n: int) -> None:
    rng = np.random.default_rng(n)
    z = rng.normal(size=(n, 3))
    tr = compiled.tree(_PLAIN, z, n, np.array([1.0, 2.0, 0.5]), n + 5)
    leaves = np.flatnonzero(tr.start >= 0)
    listed = np.concatenate([tr.perm[tr.start[i] : tr.end[i]] for i in leaves] + [[]])
    assert sorted(listed.tolist()) == list(range(n))
    assert all(tr.end[i] - tr.start[i] <= compiled.LEAF_SIZE for i in leaves)
    assert tr.leaf_of[n:].tolist() == [-1] * 5  # beyond the tree: no leaf
    for i in leaves:
        assert np.all(tr.leaf_of[tr.perm[tr.start[i] : tr.end[i]]] == i)
    _boxes_hold_their_categories(tr, z)


def test_a_moved_prototype_widens_its_leaf_and_every_ancestor() -> None:
    # learning (uncompiled body) moves prototypes half way to each input, far outside
    # the boxes they were built in; every node's box must still hold its categories
    rng = np.random.default_rng(3)
    f, n, cap = 3, 40, 64
    z = np.zeros((cap, f))
    z[:n] = rng.uniform(-1.0, 1.0, size=(n, f))
    counts = np.ones(cap, dtype=np.int64)
    tr = compiled.tree(_PLAIN, z, n, np.ones(f), cap)
    gs = np.zeros((f, f))
    gs[np.arange(f), np.arange(f)] = 0.05
    groups = Groups.of(gs, np.full(f, 1.0 / f))
    wt = rng.uniform(-3.0, 3.0, size=(60, f))
    labels = np.empty(60, dtype=np.int64)
    t, n_cat, _ = compiled.learn(
        wt, wt * 1.0, 0, 60, -1, n, 64, z, counts, *tr, np.zeros(f), np.zeros(f), 0.0,
        0.0, 0.5, 0.0, f, f, groups.index, groups.pointer, np.asarray(groups.scales),
        np.asarray(groups.weights), labels,
    )  # fmt: skip
    assert (t, n_cat) == (60, n)  # rho 0: every input moves the category it resonates with
    assert len(set(labels.tolist())) > 10
    _boxes_hold_their_categories(tr, z)


@pytest.mark.usefixtures("both")
def test_a_live_stream_loads_numba_only_when_asked_or_already_paid_for() -> None:
    # running a saved model must not cost numba's ~100 MB unasked (bench memory)
    _in_a_fresh_process(
        "import sys, numpy as np\n"
        "from behavior_hmm.cobart import CobART, _live, _compiled as c\n"
        "_live.LIVE_COMPILED_MIN = 1\n"
        "x = np.linspace(-1.0, 1.0, 60).reshape(30, 2)\n"
        "c.set_kernel('numpy'); m = CobART(window=3).fit(x); c.set_kernel('auto')\n"
        "assert m.stream()._search is None and 'numba' not in sys.modules, 'loaded unasked'\n"
        "c.set_kernel('numba'); assert m.stream()._search is not None, 'asked, not searched'\n"
        "c.set_kernel('numpy'); assert m.stream()._search is None, 'numpy chosen'\n"
        "c.set_kernel('auto'); assert m.stream()._search is not None, 'loaded, not used'\n"
    )
