"""Synthetic data and hypothesis strategies for the CobART tests (no simulator)."""

from __future__ import annotations

from typing import Any

import numpy as np
from hypothesis import strategies as st
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def s_curve(start: float, n: int = 80, still: int = 10) -> FloatArray:
    """One normalized turn: ``start`` (in [-1, 1]) to 0 along a smooth s-curve, then rest."""
    tau = np.linspace(0.0, 1.0, n)
    shape = 10 * tau**3 - 15 * tau**4 + 6 * tau**5  # minimum-jerk profile
    return np.r_[start * (1.0 - shape), np.zeros(still)]


def turn_dataset(
    starts: tuple[float, ...] = (-1.0, -0.75, -0.5, -0.25, 0.25, 0.5, 0.75, 1.0),
    two_channels: bool = False,
) -> tuple[FloatArray, list[int]]:
    """Concatenated s-curve episodes ``(X, lengths)``; optionally with a velocity channel."""
    eps = []
    for s in starts:
        ang = s_curve(s, n=int(40 + 60 * abs(s)))
        if two_channels:
            vel = np.r_[0.0, np.diff(ang)] * 20.0
            eps.append(np.c_[ang, vel])
        else:
            eps.append(ang[:, None])
    return np.concatenate(eps), [len(e) for e in eps]


@st.composite
def episodes(
    draw: st.DrawFn, max_channels: int = 2, max_episodes: int = 3, max_len: int = 30
) -> tuple[FloatArray, list[int]]:
    """Random-walk episodes in [-1, 1]: ``(X, lengths)``."""
    c = draw(st.integers(1, max_channels))
    lengths = draw(st.lists(st.integers(1, max_len), min_size=1, max_size=max_episodes))
    seed = draw(st.integers(0, 2**32 - 1))
    step = draw(st.sampled_from([0.0, 0.005, 0.05, 0.3]))
    rng = np.random.default_rng(seed)
    x = np.clip(
        rng.uniform(-1, 1, size=(1, c))
        + np.cumsum(rng.normal(0, step, size=(sum(lengths), c)), axis=0),
        -1,
        1,
    )
    return x, lengths


params = st.fixed_dictionaries(
    {
        "a": st.floats(0.0, 1.0),
        "b": st.floats(0.0, 1.0),
        "d": st.floats(0.0, 1.0),
        "alpha": st.floats(-3.0, 0.0),
        "rho": st.floats(0.0, 1.0),
        "window": st.integers(1, 6),
    }
)


def split(x: FloatArray, lengths: list[int] | None) -> list[FloatArray]:
    """Episodes of ``x``."""
    if lengths is None:
        return [x]
    return np.split(x, np.cumsum(lengths)[:-1])


def window_at(ep: FloatArray, t: int, i: int) -> FloatArray:
    """Causal window ``(I, C)`` ending at step ``t``, padded with the first reading."""
    idx = np.clip(np.arange(t - i + 1, t + 1), 0, None)
    return ep[idx]


def reference_fit(
    x: FloatArray,
    lengths: list[int] | None,
    *,
    a: float,
    b: float,
    d: float,
    alpha: float,
    rho: float,
    window: int,
    edm_scale: float,
    dcm_scale: float,
) -> tuple[list[int], list[FloatArray], list[int]]:
    """Plain-loop CobART (labels, prototypes, counts) written from the docstring."""
    from behavior_hmm.cobart import cobart_score

    protos: list[FloatArray] = []
    counts: list[int] = []
    labels: list[int] = []
    for ep in split(x, lengths):
        last = -1
        for t in range(len(ep)):
            w = window_at(ep, t, window)
            p = w if last < 0 else a * w + (1 - a) * protos[last]
            if protos:
                scores = [cobart_score(p, z, b, edm_scale, dcm_scale) for z in protos]
                k = int(np.argmax(scores))
                if scores[k] >= rho:
                    counts[k] += 1
                    protos[k] = protos[k] + d * counts[k] ** alpha * (p - protos[k])
                else:
                    k = -1
            else:
                k = -1
            if k < 0:
                protos.append(p.copy())
                counts.append(1)
                k = len(protos) - 1
            labels.append(k)
            last = k
    return labels, protos, counts


def assert_same_bits(a: tuple[Any, ...], b: tuple[Any, ...]) -> None:
    """Every array of ``a`` equals its partner in ``b`` in dtype, values and bits (signed
    zeros included)."""
    for u, v in zip(a, b, strict=True):
        assert u.dtype == v.dtype
        np.testing.assert_array_equal(u, v, strict=True)
        assert u.tobytes() == v.tobytes()
