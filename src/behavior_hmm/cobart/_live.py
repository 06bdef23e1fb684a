"""Run-time categorization of a live stream, one reading at a time."""

from __future__ import annotations

import math
import sys
from typing import TYPE_CHECKING, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from behavior_hmm.cobart import _compiled as compiled
from behavior_hmm.cobart._engine import aligned_zeros
from behavior_hmm.cobart._exact import score_of
from behavior_hmm.errors import ConfigError, DatasetError

if TYPE_CHECKING:
    from behavior_hmm.cobart._cobart import CobART


#: From this many categories a live stream may search with the compiled kernels' tree
#: (:func:`live_kernels`) instead of screening every category with one product. A live
#: update over the turn & approach CBLM's 2,310 observation categories: 48.1 µs screened,
#: 6.1 µs searched (medians); over 98: 12.6 and 5.5 µs. Smaller streams keep the screen:
#: a primitive stream's every mismatch is read each cycle (primitive recognition), which
#: a search would have to screen again.
LIVE_COMPILED_MIN: Final[int] = 256


def live_kernels() -> compiled.Kernels | None:
    """The compiled kernels for a live stream, or ``None`` for the numpy path.

    With CobART's kernels set to ``"numba"`` (:func:`~behavior_hmm.cobart._compiled.
    set_kernel`), always; under ``"auto"`` only when numba is loaded in this process
    already (it has trained a model, or called ``_compiled.warm()``): loading numba costs
    ~100 MB of memory and ~0.4 s, which a process that only runs a saved model should not
    pay unasked (``bench memory``: ``generate`` on a CBLM); ``"numpy"``: never.
    """
    setting = compiled._switch.setting
    if setting == "numba" or (setting == "auto" and "numba" in sys.modules):
        return compiled.active()
    return None


class LiveCategorizer:
    """Categorize a live stream reading by reading, without learning.

    Keeps its own window of the last ``I`` readings (the first reading after
    :meth:`reset` fills it, as the offline pass pads an episode) and the last best
    category. Over one episode it returns exactly what ``CobART.categorize`` returns
    for that episode. It works on a snapshot of the categories taken when it was
    created; later learning does not affect it.

    From ``LIVE_COMPILED_MIN`` categories on (below ``INDEX_MIN_CATEGORIES``), where
    :func:`live_kernels` allows, an update searches the compiled kernels' tree for the
    exact winner (module ``_compiled``; the same winner and score). The search is
    compiled (or loaded from numba's cache) when the stream is created, never inside an
    update.

    Obtain one from :meth:`CobART.stream`.
    """

    def __init__(self, model: CobART) -> None:
        pred = model._predictor()
        self._pred = pred
        self.window = model._fit.window
        self.n_channels = model.n_features_in_
        self.rho = model._fit.rho
        self.n_categories = pred.K
        i, c = self.window, self.n_channels
        self._ic = i * c
        self._shape = (c,)
        self._buf = aligned_zeros((2 * i, c))
        self._views = [self._buf[j + 1 : j + 1 + i].reshape(-1) for j in range(i)]
        self._wt = aligned_zeros(pred.F)
        self._raw = self._wt[: self._ic]
        self._diff = self._wt[self._ic :]
        self._awt = aligned_zeros(pred.F)
        p = pred
        self._hot = (
            self._buf, self._views, self._raw, self._diff, self._wt, self._awt, i, c, p.a,
            p.omaz_rows, p.pt, p.pt_col, p.gm2, p.top, p.pn2, self.rho, p.best,
            p.index is not None,
        )  # fmt: skip
        self._search: compiled.CompiledPredictor | None = None
        if pred.index is None and pred.K >= LIVE_COMPILED_MIN:
            kern = live_kernels()  # numba loaded here if at all, never in an update
            if kern is not None:
                self._search = pred.compiled_search(kern)
                self._search.best(pred.pt, -1)  # compiled now, or loaded from the cache
        self._stale = False
        self.reset()

    @property
    def mismatch(self) -> NDArray[np.float64]:
        """``1 - score`` of every category for the last reading, shape ``(K,)``.

        A read-only view of a buffer that every :meth:`update` refreshes in place (keep
        a reference instead of copying each cycle); clipped scores may exceed 1 before
        clipping. Where an update searches (``LIVE_COMPILED_MIN`` categories on with
        numba, ``INDEX_MIN_CATEGORIES`` on without), it scores only the categories that
        could win, and reading this property scores all of them: there, read the
        property after each update instead of keeping the view.
        """
        pred = self._pred
        if self._stale:
            pred.query()  # a search sets no query
            if pred.index is not None:
                pred.index.mismatches(pred.paug, pred.v, pred.s)
            else:
                pred.screen()
            self._stale = False
        view = pred.v.view()
        view.flags.writeable = False
        return view

    def reset(self) -> None:
        """Start a new episode: empty window, no last category."""
        self._pos = -1
        self._last = -1

    def update(self, reading: ArrayLike) -> tuple[int, bool, float]:
        """Categorize the window ending with ``reading``.

        Parameters
        ----------
        reading
            One filtered, normalized reading, shape ``(C,)``.

        Returns
        -------
        category, novel, score
            Best category, whether its score is below the vigilance ``rho``, and the
            score in [0, 1].

        Raises
        ------
        ConfigError
            Wrong number of channels.
        DatasetError
            NaN or inf in the reading.
        """
        r = np.asarray(reading, dtype=np.float64)
        if r.shape != self._shape:
            if r.ndim == 0 and self._shape == (1,):
                r = r.reshape(1)
            else:
                raise ConfigError(f"reading must have shape {self._shape}, got {np.shape(reading)}")
        if not all(map(math.isfinite, r.tolist())):
            raise DatasetError("NaN or infinite value in live reading")
        # fmt: off
        (buf, views, raw, diff, wt, awt, i, c, a, omaz, pt, pt_col, gm2, top, pn2, rho, best,
         indexed) = self._hot
        # fmt: on
        pos = self._pos
        if pos < 0:
            buf[:] = r
            pos = 0
        else:
            pos += 1
            if pos == i:
                pos = 0
            buf[pos] = r
            buf[pos + i] = r
        self._pos = pos
        view = views[pos]
        np.copyto(raw, view)
        if i > 1:
            np.subtract(view[c:], view[:-c], out=diff)
        k = self._last
        if k < 0:
            np.copyto(pt, wt)
        else:
            np.multiply(wt, a, out=awt)
            np.add(awt, omaz[k], out=pt)
        search = self._search
        if search is not None:
            k, miss = search.best(pt, k)
            self._stale = True  # no category but the winner's neighbours was scored
        else:
            np.multiply(gm2, pt_col, out=top)
            np.dot(pt, top, out=pn2)
            k, miss = best()
            self._stale = indexed  # the index scored only the categories that could win
        score = score_of(miss)
        self._last = k
        return k, score < rho, score
