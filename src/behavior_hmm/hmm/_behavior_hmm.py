"""The Behavior-HMM estimator {S, O, A, B, C, π} (thesis §4.2–4.3), in log space.

The motion generators G live in :mod:`behavior_hmm.generators`; this class holds the
counted tables, plans the most likely observation path to a goal and decodes the
states along it. States are generic: motion primitives in SBLM, learned behaviors in
CBLM.
"""

from __future__ import annotations

import numbers
from collections import OrderedDict
from collections.abc import Mapping
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.sparse import csr_array

from behavior_hmm._estimator import Estimator
from behavior_hmm.errors import (
    ConfigError,
    DatasetError,
    ModelFileError,
    NotFittedError,
    UnreachableGoalError,
)
from behavior_hmm.hmm._counting import (
    Counting,
    add_counts,
    add_tables,
    count_density,
    count_emissions,
    count_transitions,
    episode_starts,
    normalize,
    safe_log,
)
from behavior_hmm.hmm._paths import GoalTree, PathSelfLoops, goal_tree, path_graph, walk
from behavior_hmm.hmm._plan import Plan
from behavior_hmm.hmm._tables import (
    CSR_PARTS,
    LogTable,
    canonical,
    check_counts,
    csr_arrays,
    normalize_sparse,
)
from behavior_hmm.hmm._viterbi import TreeViterbi, emission_decode, viterbi_log

OnImpossible = Literal["raise", "emissions"]
Category = int | np.integer[Any]  # an observation category index

_COUNTINGS = ("changes", "steps")
_SELF_LOOP_RULES = ("drop", "keep")
_ON_IMPOSSIBLE = ("raise", "emissions")

#: The count tables a model file holds in compressed sparse rows, with their columns'
#: axis: ``{name}_indptr``, ``{name}_indices`` and ``{name}_counts`` each.
_SPARSE_TABLES: dict[str, str] = {"A": "N", "B": "M", "C": "M"}
#: The count vectors a model file holds densely, shape (N,).
_VECTORS = ("pi_counts", "start_counts")
#: Most states a model may have: A is held dense (N × N), and at this size one of its
#: tables is 64 MiB. Observation categories have no such bound: B and C are sparse.
MAX_DENSE_STATES = 2896


class BehaviorHMM(Estimator):
    """Behavior-HMM estimated by counting (thesis table 4.3), probabilities in log space.

    Parameters
    ----------
    n_states, n_observations
        Number of states (primitives or behaviors) and observation categories; by
        default ``max label + 1`` of the training data.
    counting
        How A and C are counted. ``"changes"`` (default, the thesis): a transition
        is counted when the label changes between consecutive control cycles, and one
        self transition is added to every label seen (``self_transitions=True``), so
        table 4.3 comes out exactly. ``"steps"``: every pair of consecutive cycles is
        counted, so ``a_ii ≈ 1 − 1/(mean run length)``.
    self_transitions
        Whether self transitions exist at all; ``False`` makes the diagonals of A and
        C structural zeros (smoothing leaves them zero too).
    smoothing
        Add-k pseudo-count added to every cell of A, B, C, π before normalizing
        (0 = the thesis's plain counting). A row without any count stays all zero
        (log −inf) when ``smoothing == 0`` and becomes uniform otherwise.
    path_self_loops
        ``"drop"`` (default): the most likely path uses ``c_ij / (1 − c_ii)``, the
        probability that the next *different* category is j; ``"keep"``: ``c_ij``
        as counted.
    on_impossible
        What :meth:`viterbi` and :meth:`plan` do when no state sequence can explain
        the observations under A: ``"raise"`` (default) raises
        :class:`~behavior_hmm.errors.UnreachableGoalError`; ``"emissions"`` decodes
        each element alone as ``argmax_j π_j b_j(o)`` (the state most often seen with
        that observation) and reports ``log_prob = -inf``.

    Attributes
    ----------
    n_states_, n_observations_ : int
    A_counts_, B_counts_, C_counts_ : ndarray of int64
        Raw counts, shapes (N, N), (N, M), (M, M).
    pi_counts_, start_counts_ : ndarray of int64, shape (N,)
        Control cycles spent in each state; episodes starting in each state.
    log_A_, log_B_, log_C_, log_pi_ : ndarray of float64
        Log probabilities; ``-inf`` for impossible entries, never NaN.
    start_prob_first_ : ndarray of float64, shape (N,)
        Distribution of the first state of an episode (for reference; π is the
        density, which is the right prior for a plan made mid-behavior).

    Notes
    -----
    The counts are sums over episodes, so :meth:`partial_fit` adds new episodes to a
    fitted model exactly: the tables equal those of :meth:`fit` on all the episodes.

    Examples
    --------
    >>> hmm = BehaviorHMM().fit([0, 0, 1, 1], [0, 1, 2, 2])
    >>> hmm.plan(0, 2).observations
    (0, 1, 2)
    """

    _PLAN_CACHE_SIZE = 4096

    def __init__(
        self,
        *,
        n_states: int | None = None,
        n_observations: int | None = None,
        counting: Counting = "changes",
        self_transitions: bool = True,
        smoothing: float = 0.0,
        path_self_loops: PathSelfLoops = "drop",
        on_impossible: OnImpossible = "raise",
    ) -> None:
        self.n_states = n_states
        self.n_observations = n_observations
        self.counting = counting
        self.self_transitions = self_transitions
        self.smoothing = smoothing
        self.path_self_loops = path_self_loops
        self.on_impossible = on_impossible

    # ------------------------------------------------------------------ params
    def _params_changed(self) -> None:
        """``set_params`` clears the planning caches (they depend on the parameters)."""
        if hasattr(self, "log_A_"):
            self._reset_caches()

    @property
    def params(self) -> dict[str, Any]:
        """JSON-ready constructor parameters, for the model file (see :meth:`from_arrays`)."""
        return self.get_params()

    def _validate_params(self) -> None:
        for name in ("n_states", "n_observations"):
            value = getattr(self, name)
            if value is not None and (
                isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1
            ):
                raise ConfigError(f"{name} must be None or an integer >= 1, got {value!r}")
        if self.counting not in _COUNTINGS:
            raise ConfigError(f"counting must be one of {_COUNTINGS}, got {self.counting!r}")
        if not isinstance(self.self_transitions, bool | np.bool_):
            raise ConfigError(f"self_transitions must be a bool, got {self.self_transitions!r}")
        s = self.smoothing
        bad_type = isinstance(s, bool) or not isinstance(s, numbers.Real)
        if bad_type or not (np.isfinite(s) and s >= 0):
            raise ConfigError(f"smoothing must be a finite number >= 0, got {s!r}")
        if self.path_self_loops not in _SELF_LOOP_RULES:
            raise ConfigError(
                f"path_self_loops must be one of {_SELF_LOOP_RULES}, got {self.path_self_loops!r}"
            )
        if self.on_impossible not in _ON_IMPOSSIBLE:
            raise ConfigError(
                f"on_impossible must be one of {_ON_IMPOSSIBLE}, got {self.on_impossible!r}"
            )

    # --------------------------------------------------------------------- fit
    def fit(
        self, states: ArrayLike, observations: ArrayLike, lengths: ArrayLike | None = None
    ) -> BehaviorHMM:
        """Count A, B, C, π from labelled control cycles.

        Parameters
        ----------
        states
            State index per control cycle (motion primitive id, or behavior id in CBLM).
        observations
            Observation category index per control cycle, same length.
        lengths
            Control cycles per episode, summing to the number of samples; transitions
            are never counted across episodes. ``None`` = one episode.

        Returns
        -------
        self
        """
        self._validate_params()
        s, o, lens = _checked_data(states, observations, lengths)
        n = _n_labels(s, self.n_states, "states", "n_states")
        m = _n_labels(o, self.n_observations, "observations", "n_observations")
        self._set_tables(self._count(s, o, lens, n, m))
        return self

    def partial_fit(
        self, states: ArrayLike, observations: ArrayLike, lengths: ArrayLike | None = None
    ) -> BehaviorHMM:
        """Add the counts of new episodes to the model's (``fit`` if not fitted yet).

        The new episodes are counted as :meth:`fit` counts them and added to the stored
        counts (``A_counts_``, ``B_counts_``, ``C_counts_``, ``pi_counts_``,
        ``start_counts_``); the probabilities and log tables are then normalized from
        the totals under the current ``smoothing``. The result is identical, bit for
        bit, to :meth:`fit` on the earlier and the new episodes together (with the same
        parameters and the same sizes ``n_states_``, ``n_observations_``): with
        ``counting="changes"`` the one self transition of each state or category is
        kept once, not added again. An episode cannot be split across calls (the new
        ones start afresh: no transition is counted from the last sample of the
        earlier data).

        The tables grow with the data: a state or observation category index beyond
        ``n_states_ - 1`` / ``n_observations_ - 1`` (a new primitive, a new category)
        appends rows and columns of zero counts before the new counts are added. With
        ``n_states`` / ``n_observations`` set (e.g. raised with ``set_params``) the
        tables take that size instead, as in :meth:`fit`; it may not be smaller than
        the fitted size. Planning and decoding caches (goal trees, Viterbi messages,
        plans) are dropped, so :meth:`plan` and :meth:`viterbi` answer as a model
        fitted on everything.

        Parameters
        ----------
        states
            State index per control cycle of the new episodes.
        observations
            Observation category index per control cycle, same length.
        lengths
            Control cycles per new episode, summing to the number of new samples.
            ``None`` = one episode.

        Returns
        -------
        self

        Raises
        ------
        DatasetError
            The new data are invalid, as :meth:`fit` reports it (nothing is changed).
        ConfigError
            An invalid parameter; ``counting`` or ``self_transitions`` changed since
            the counts were made (they would mix two rules: call :meth:`fit`);
            ``n_states`` / ``n_observations`` smaller than the fitted tables.

        Examples
        --------
        >>> hmm = BehaviorHMM().fit([0, 0, 1], [0, 1, 1])
        >>> hmm.partial_fit([1, 2], [1, 2]).n_states_
        3
        >>> hmm.plan(0, 2).observations
        (0, 1, 2)
        """
        if not hasattr(self, "log_A_"):
            return self.fit(states, observations, lengths)
        self._validate_params()
        s, o, lens = _checked_data(states, observations, lengths)
        n = _grown_size(s, self.n_states, self.n_states_, "states", "n_states")
        m = _grown_size(
            o, self.n_observations, self.n_observations_, "observations", "n_observations"
        )
        rule = (str(self.counting), bool(self.self_transitions))
        counted = getattr(self, "_counted_with", rule)
        if counted != rule:
            raise ConfigError(
                f"the counts were made with counting={counted[0]!r}, "
                f"self_transitions={counted[1]!r}, now {rule[0]!r}, {rule[1]!r}: they cannot "
                "be added up; call fit to count everything again"
            )
        new = self._count(s, o, lens, n, m)
        transitions: dict[str, Any] = {"counting": self.counting, "self_transitions": rule[1]}
        counts: dict[str, Any] = {
            "A": add_tables(canonical(csr_array(self.A_counts_)), new["A"], **transitions),
            "B": add_tables(self.B_counts_, new["B"]),
            "C": add_tables(self.C_counts_, new["C"], **transitions),
            "pi": add_counts(self.pi_counts_, new["pi"]),
            "start_prob_first": add_counts(self.start_counts_, new["start_prob_first"]),
        }
        self._set_tables(counts)
        return self

    def _count(
        self,
        s: NDArray[np.int64],
        o: NDArray[np.int64],
        lens: NDArray[np.int64],
        n: int,
        m: int,
    ) -> dict[str, Any]:
        """Count tables of checked data (n states, m categories): A, B, C sparse."""
        kw: dict[str, Any] = {"counting": self.counting, "self_transitions": self.self_transitions}
        return {
            "A": count_transitions(s, n, lens, **kw),
            "B": count_emissions(s, o, n, m),
            "C": count_transitions(o, m, lens, **kw),
            "pi": count_density(s, n),
            "start_prob_first": count_density(s[episode_starts(lens)], n),
        }

    def _set_tables(self, counts: Mapping[str, Any]) -> None:
        """Hold the counts (A dense, B and C sparse) and their log probabilities."""
        k = float(self.smoothing)
        no_self = not self.self_transitions
        a_counts = counts["A"]  # sparse from counting and files; dense from tests' tables
        self.A_counts_ = np.asarray(
            a_counts.toarray() if hasattr(a_counts, "toarray") else a_counts, dtype=np.int64
        )
        self.B_counts_ = canonical(counts["B"])
        self.C_counts_ = canonical(counts["C"])
        self.pi_counts_ = np.array(counts["pi"], dtype=np.int64)
        self.start_counts_ = np.array(counts["start_prob_first"], dtype=np.int64)
        self.n_states_ = int(self.pi_counts_.shape[0])
        self.n_observations_ = int(self.C_counts_.shape[0])
        self.log_A_ = safe_log(normalize(self.A_counts_, k, zero_diagonal=no_self))
        self.log_B_ = LogTable(*normalize_sparse(self.B_counts_, k, zero_diagonal=False))
        self.log_C_ = LogTable(*normalize_sparse(self.C_counts_, k, zero_diagonal=no_self))
        self.log_pi_ = safe_log(normalize(self.pi_counts_, k, zero_diagonal=False))
        self.start_prob_first_ = normalize(self.start_counts_, k, zero_diagonal=False)
        # the rule the counts were made with: partial_fit adds counts only under the same one
        self._counted_with: tuple[str, bool] = (str(self.counting), bool(self.self_transitions))
        self._reset_caches()

    def _check_fitted(self) -> None:
        if not hasattr(self, "log_A_"):
            raise NotFittedError("this BehaviorHMM is not fitted yet; call fit() or from_arrays()")

    def _reset_caches(self) -> None:
        self._cache_params: tuple[str, str] = (self.path_self_loops, self.on_impossible)
        self._graph_rev: Any = None
        self._trees: dict[int, GoalTree] = {}
        self._decoders: dict[int, TreeViterbi] = {}
        self._plans: OrderedDict[tuple[Any, Any], Plan] = OrderedDict()

    # ---------------------------------------------------------------- planning
    def _check_observation(self, value: Any, name: str) -> int:
        if type(value) is int and 0 <= value < self.n_observations_:
            return value  # the case of every control cycle, without the ABC checks below
        if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Integral):
            raise ConfigError(f"{name} must be an observation category index, got {value!r}")
        v = int(value)
        if not 0 <= v < self.n_observations_:
            raise ConfigError(
                f"{name}={v} is not an observation category of this model "
                f"(0 to {self.n_observations_ - 1})"
            )
        return v

    def _tree(self, goal: int) -> GoalTree:
        tree = self._trees.get(goal)
        if tree is None:
            if self._graph_rev is None:
                self._graph_rev = path_graph(self.log_C_, self.path_self_loops)
            tree = goal_tree(self._graph_rev, goal)
            self._trees[goal] = tree
        return tree

    def _path(self, current: int, goal: int) -> tuple[list[int], float]:
        tree = self._tree(goal)
        cost = float(tree.cost[current])
        if not np.isfinite(cost):
            raise UnreachableGoalError(
                f"goal observation category {goal} cannot be reached from category {current}: "
                "no chain of observed transitions leads there"
            )
        return walk(tree, current), 0.0 - cost

    def path_log_prob(self, o_current: Category, o_goal: Category) -> float:
        """Log probability of the most likely observation path, ``-inf`` if there is none.

        The same number as ``plan(o_current, o_goal).path_log_prob``, read off the goal's
        cached shortest-path tree without walking the path or decoding states (what a
        controller needs to compare several candidate goals in one control cycle).
        """
        self._check_fitted()
        self._sync_caches()
        c = self._check_observation(o_current, "o_current")
        g = self._check_observation(o_goal, "o_goal")
        return 0.0 - float(self._tree(g).cost[c])

    def plannable_from(self, goals: Any) -> NDArray[np.bool_]:
        """Which observation categories :meth:`plan` succeeds from toward any of ``goals``.

        ``out[i]`` is ``can_plan(i, g)`` for some ``g`` in ``goals``: an observation path
        leads from ``i`` to ``g`` and some state sequence explains it. Read off the goals'
        cached trees and Viterbi messages (computed here where :meth:`prepare_goals` has
        not). A controller whose start category has no plan picks among these, best
        match first, instead of trying the categories one by one.
        """
        self._check_fitted()
        self._sync_caches()
        out = np.zeros(self.n_observations_, dtype=bool)
        for goal in goals:
            g = self._check_observation(int(goal), "goal")
            nodes = np.flatnonzero(np.isfinite(self._tree(g).cost) & ~out).tolist()
            if self.on_impossible == "raise":  # can_plan is exactly _decodable
                ok = self._decoder(g).startable(nodes)
            else:
                ok = [self.can_plan(u, g) for u in nodes]
            out[[u for u, yes in zip(nodes, ok, strict=True) if yes]] = True
        return out

    def most_likely_path(self, o_current: Category, o_goal: Category) -> tuple[int, ...]:
        """Most likely observation path from ``o_current`` to ``o_goal`` (both included).

        Dijkstra on edge costs ``−log c_ij`` (see ``path_self_loops``); the tree
        towards each goal is computed once and cached.

        Raises
        ------
        UnreachableGoalError
            No chain of observed transitions leads from ``o_current`` to ``o_goal``.
        """
        self._check_fitted()
        self._sync_caches()
        c = self._check_observation(o_current, "o_current")
        g = self._check_observation(o_goal, "o_goal")
        return tuple(self._path(c, g)[0])

    def _sync_caches(self) -> None:
        if self._cache_params != (self.path_self_loops, self.on_impossible):
            self._reset_caches()

    def viterbi(
        self, observations: ArrayLike, *, on_impossible: OnImpossible | None = None
    ) -> tuple[NDArray[np.int64], float]:
        """Most likely state sequence for an observation sequence (log space).

        Parameters
        ----------
        observations
            Observation category per element, shape (T,), T ≥ 1.
        on_impossible
            Overrides the estimator's ``on_impossible`` for this call.

        Returns
        -------
        states : ndarray of int64, shape (T,)
        log_prob : float
            ``log P(states, observations)`` under π, A, B; ``-inf`` if the emission
            fallback was used.

        Raises
        ------
        UnreachableGoalError
            Every state sequence is impossible (and the fallback is off or cannot help).
        """
        self._check_fitted()
        obs = _as_labels(observations, "observations")
        if obs.size == 0:
            raise DatasetError("cannot decode an empty observation sequence", field="observations")
        if obs.max() >= self.n_observations_:
            row = int(np.argmax(obs >= self.n_observations_))
            raise DatasetError(
                f"observation category {int(obs[row])} does not exist in this model "
                f"({self.n_observations_} categories)",
                row=row,
                field="observations",
            )
        rule = self.on_impossible if on_impossible is None else on_impossible
        if rule not in _ON_IMPOSSIBLE:
            raise ConfigError(f"on_impossible must be one of {_ON_IMPOSSIBLE}, got {rule!r}")
        states, log_prob, _ = self._decode(obs, rule)
        return states, log_prob

    def _decode(
        self, obs: NDArray[np.int64], rule: str, *, compiled: bool = True
    ) -> tuple[NDArray[np.int64], float, Literal["viterbi", "emissions"]]:
        states, log_prob, dead = viterbi_log(
            self.log_pi_, self.log_A_, self.log_B_, obs, compiled=compiled
        )
        if dead < 0:
            return states, log_prob, "viterbi"
        if rule == "emissions":
            states, bad = emission_decode(self.log_pi_, self.log_B_, obs)
            if bad < 0:
                return states, float("-inf"), "emissions"
            raise UnreachableGoalError(
                f"observation category {int(obs[bad])} (position {bad}) was never seen with "
                "any state, so no state can be decoded for it"
            )
        raise UnreachableGoalError(
            f"no state sequence can produce these observations: every sequence becomes "
            f"impossible at position {dead} (observation category {int(obs[dead])}); fit with "
            "smoothing > 0 or use on_impossible='emissions'"
        )

    def plan(self, o_current: Category, o_goal: Category) -> Plan:
        """Plan from the current to the goal observation category (thesis Algorithm 1).

        Most likely observation path, then Viterbi states along it, collapsed into
        segments with their exit observations. Per goal, the shortest-path tree and
        the Viterbi messages of its nodes are computed once (all paths to a goal
        share suffixes); whole plans are cached per ``(o_current, o_goal)`` (LRU),
        so a per-cycle re-plan is a dict lookup.

        Raises
        ------
        UnreachableGoalError
            The goal cannot be reached, or no state sequence explains the path (with
            ``on_impossible="raise"``). Raised before anything is executed.
        """
        try:
            plans = self._plans
        except AttributeError:
            raise NotFittedError(
                "this BehaviorHMM is not fitted yet; call fit() or from_arrays()"
            ) from None
        if self._cache_params != (self.path_self_loops, self.on_impossible):
            self._reset_caches()
            plans = self._plans
        key = (o_current, o_goal)
        cached = plans.get(key)
        if cached is not None:
            plans.move_to_end(key)
            return cached
        c = self._check_observation(o_current, "o_current")
        g = self._check_observation(o_goal, "o_goal")
        path, path_log_prob = self._path(c, g)
        state_list, log_prob = self._decoder(g).decode(path)
        decoding: Literal["viterbi", "emissions"] = "viterbi"
        if not state_list:  # impossible: the forward pass explains where, or falls back
            # a plan's path is short and may be decoded inside a control cycle: the numpy
            # pass, so that no cycle is the one that first imports numba (~0.7 s)
            states_arr, log_prob, decoding = self._decode(
                np.asarray(path, dtype=np.int64), self.on_impossible, compiled=False
            )
            state_list = states_arr.tolist()
        observations = tuple(path)
        states = tuple(state_list)
        result = Plan(
            observations=observations,
            states=states,
            path_log_prob=path_log_prob,
            log_prob=log_prob,
            decoding=decoding,
        )
        plans[(c, g)] = result
        if len(plans) > self._PLAN_CACHE_SIZE:
            plans.popitem(last=False)
        return result

    def prepare_goals(self, goals: Any) -> None:
        """Build the shortest-path trees of ``goals`` and their Viterbi messages now.

        Controllers call this before the robot moves, so that re-planning toward any of
        these goals later is a cached walk instead of a Dijkstra run inside a 16 ms
        cycle, and a category first seen in the middle of a run does not compute the
        messages of its whole path to the goal there (a few ms for a path of hundreds
        of categories). Each goal's messages are computed for every category that
        reaches it: ~10 µs a category (25 ms on ~2,300 categories, 0.5 s and ~45 MB on
        100,000). A smoothed B (whole N-vector messages) keeps computing them on first
        use, as its messages would take N × 8 bytes per category.
        """
        self._check_fitted()
        self._sync_caches()
        for goal in goals:
            g = self._check_observation(int(goal), "goal")
            tree = self._tree(g)
            self._decoder(g).compute(np.flatnonzero(np.isfinite(tree.cost)).tolist())

    def state_scores(self, o_current: Category, o_goal: Category) -> NDArray[np.float64]:
        """Backward Viterbi message of the current observation toward the goal.

        ``scores[i]`` is the best log probability of the planned path from
        ``o_current`` to ``o_goal`` when state ``i`` emits ``o_current`` (π excluded).
        ``plan`` takes ``argmax(log π + scores)`` as its first state; a caller that
        tracks the states already visited can use its own prior instead (see
        ``models._policy.SimplePolicy``, ``state_decoding="history"``).

        Raises
        ------
        UnreachableGoalError
            The goal cannot be reached from ``o_current``.
        """
        self._check_fitted()
        self._sync_caches()
        c = self._check_observation(o_current, "o_current")
        g = self._check_observation(o_goal, "o_goal")
        if not self._decodable(c, g):
            self.plan(c, g)  # raises (unreachable, or no state sequence) or falls back
        return self._decoder(g)._message(c)

    def can_plan(self, o_current: Category, o_goal: Category) -> bool:
        """Whether :meth:`plan` succeeds from ``o_current`` to ``o_goal``.

        The usual case (reachable, and decodable under A) is read off the cached goal
        tree and Viterbi messages without building the plan; a controller asks this on
        every change of category, and a plan's path can be hundreds of categories long.
        """
        self._check_fitted()
        self._sync_caches()
        c = self._check_observation(o_current, "o_current")
        g = self._check_observation(o_goal, "o_goal")
        if self._decodable(c, g):
            return True
        if self.on_impossible == "raise":  # plan would raise: unreachable or undecodable
            return False
        try:
            self.plan(c, g)  # the emission fallback may still give a plan
        except UnreachableGoalError:
            return False
        return True

    def _decoder(self, goal: int) -> TreeViterbi:
        decoder = self._decoders.get(goal)
        if decoder is None:
            tree = self._tree(goal)
            decoder = TreeViterbi(tree.next_node, goal, self.log_pi_, self.log_A_, self.log_B_)
            self._decoders[goal] = decoder
        return decoder

    def _decodable(self, current: int, goal: int) -> bool:
        """The goal is reachable and some state sequence explains the path (π, A, B).

        Exactly when ``plan`` finds a Viterbi decoding (``TreeViterbi.decode``: the best
        start score ``max(log π + V_current)`` is finite).
        """
        if not np.isfinite(self._tree(goal).cost[current]):
            return False
        message = self._decoder(goal)._message(current)
        return bool(np.isfinite(np.max(self.log_pi_ + message)))

    def dense_probabilities(self) -> dict[str, NDArray[np.float64]]:
        """π, A, B and C as dense probability arrays (hmmlearn's ``startprob_`` ...).

        For small models and for other libraries: B is (N, M) and C is (M, M), so this
        allocates what the sparse tables avoid. Normalized from the counts as the model
        normalizes them (without smoothing the same numbers, to the bit, as ``exp`` of
        the log tables would give only approximately).
        """
        self._check_fitted()
        k = float(self.smoothing)
        no_self = not self.self_transitions
        return {
            "pi": normalize(self.pi_counts_, k, zero_diagonal=False),
            "A": normalize(self.A_counts_, k, zero_diagonal=no_self),
            "B": normalize(self.B_counts_.toarray(), k, zero_diagonal=False),
            "C": normalize(self.C_counts_.toarray(), k, zero_diagonal=no_self),
        }

    # ------------------------------------------------------------ persistence
    def to_arrays(self) -> dict[str, NDArray[Any]]:
        """Learned counts as plain arrays for the model file (no pickle).

        The probabilities are not stored: they are the counts normalized under the
        parameters (see :attr:`params`), so a loaded model's are the same to the bit.
        Keys: ``A``, ``B`` and ``C`` as compressed sparse rows, ``{X}_indptr`` (rows + 1),
        ``{X}_indices`` and ``{X}_counts`` (one per counted entry, column indices
        increasing within each row, no zero count); ``pi_counts`` and ``start_counts``
        (N,). All int64. Save :attr:`params` beside them.
        """
        self._check_fitted()
        tables = {
            "A": canonical(csr_array(self.A_counts_)),
            "B": self.B_counts_,
            "C": self.C_counts_,
        }
        arrays: dict[str, NDArray[Any]] = {}
        for name, table in tables.items():
            arrays.update(csr_arrays(name, table))
        arrays["pi_counts"] = self.pi_counts_.copy()
        arrays["start_counts"] = self.start_counts_.copy()
        return arrays

    @classmethod
    def from_arrays(
        cls, arrays: Mapping[str, NDArray[Any]], params: Mapping[str, Any]
    ) -> BehaviorHMM:
        """Rebuild a fitted model from :meth:`to_arrays` output and :attr:`params`.

        Every array is checked, as arrays from a stranger's file: presence, integer
        dtype, shapes, canonical sparse rows (see :func:`~behavior_hmm.hmm._tables.
        check_counts`), non-negative counts, emissions that add up to the state
        densities, and no self transition where the parameters have none. Nothing is
        allocated from a claimed size: N is the length of ``pi_counts`` and M that of
        ``C_indptr`` minus one, and A (held dense) is refused beyond
        :data:`MAX_DENSE_STATES` states.

        Raises
        ------
        ModelFileError
            Anything is missing, malformed or inconsistent.
        """
        names = cls._param_names()
        unknown = sorted(set(params) - set(names))
        if unknown:
            raise ModelFileError(f"unknown Behavior-HMM parameters in model file: {unknown}")
        model = cls(**dict(params))
        try:
            model._validate_params()
        except ConfigError as err:
            raise ModelFileError(f"invalid Behavior-HMM parameters in model file: {err}") from err
        counts = _checked_arrays(arrays, bool(model.self_transitions))
        n, m = counts["B"].shape
        for name, size in (("n_states", n), ("n_observations", m)):
            declared = getattr(model, name)
            if declared is not None and declared != size:
                raise ModelFileError(
                    f"{name}={declared} in the parameters but the arrays have {size}"
                )
        model._set_tables(counts)
        return model


# ---------------------------------------------------------------- validation
def _checked_data(
    states: ArrayLike, observations: ArrayLike, lengths: ArrayLike | None
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """States, observations and episode lengths checked as ``fit`` needs them."""
    s = _as_labels(states, "states")
    o = _as_labels(observations, "observations")
    if s.size != o.size:
        raise DatasetError(
            f"states has {s.size} samples but observations has {o.size}", field="observations"
        )
    if s.size == 0:
        raise DatasetError("no samples to fit a Behavior-HMM on", field="states")
    return s, o, _as_lengths(lengths, s.size)


def _as_labels(values: ArrayLike, name: str) -> NDArray[np.int64]:
    a = np.asarray(values)
    if a.ndim != 1:
        raise DatasetError(f"{name} must be a 1-D sequence, got shape {a.shape}", field=name)
    if a.size == 0:
        return a.astype(np.int64)
    if a.dtype.kind not in "iu":
        raise DatasetError(f"{name} must hold integer labels, got dtype {a.dtype}", field=name)
    if a.min() < 0:
        row = int(np.argmax(a < 0))
        raise DatasetError(f"negative label {int(a[row])}", row=row, field=name)
    return a.astype(np.int64, copy=False)


def _as_lengths(lengths: ArrayLike | None, n_samples: int) -> NDArray[np.int64]:
    if lengths is None:
        return np.array([n_samples], dtype=np.int64)
    lens = np.asarray(lengths)
    if lens.ndim != 1 or lens.size == 0 or lens.dtype.kind not in "iu":
        raise DatasetError("lengths must be a non-empty 1-D sequence of integers", field="lengths")
    if lens.min() < 1:
        episode = int(np.argmax(lens < 1))
        raise DatasetError(f"empty episode (length {int(lens[episode])})", episode=episode)
    if int(lens.sum()) != n_samples:
        raise DatasetError(
            f"lengths sum to {int(lens.sum())} but there are {n_samples} samples", field="lengths"
        )
    return lens.astype(np.int64, copy=False)


def _n_labels(labels: NDArray[np.int64], declared: int | None, field: str, param: str) -> int:
    top = int(labels.max())
    if declared is None:
        return top + 1
    if top >= declared:
        row = int(np.argmax(labels >= declared))
        raise DatasetError(f"label {top} does not fit {param}={declared}", row=row, field=field)
    return int(declared)


def _grown_size(
    labels: NDArray[np.int64], declared: int | None, current: int, field: str, param: str
) -> int:
    """Table size for ``partial_fit``: the fitted size, grown to fit the new labels.

    With ``declared`` (the parameter) set, that size, as in ``fit``: the labels must fit
    it (the same :class:`DatasetError` as ``fit``) and it may not shrink the tables.
    """
    if declared is None:
        return max(current, int(labels.max()) + 1)
    size = _n_labels(labels, declared, field, param)
    if size < current:
        raise ConfigError(
            f"{param}={size} is smaller than the fitted model's {current}: tables cannot "
            "shrink; call fit to start again"
        )
    return size


def _checked_arrays(arrays: Mapping[str, Any], self_transitions: bool) -> dict[str, Any]:
    """The counts of :meth:`BehaviorHMM.to_arrays`, checked, keyed as ``_set_tables`` wants."""
    expected = set(_VECTORS)
    for name in _SPARSE_TABLES:
        expected |= {f"{name}_{part}" for part in CSR_PARTS}
    missing = sorted(expected - set(arrays))
    if missing:
        raise ModelFileError(f"Behavior-HMM arrays missing from model file: {missing}")
    extra = sorted(set(arrays) - expected)
    if extra:
        raise ModelFileError(f"unexpected Behavior-HMM arrays in model file: {extra}")
    for key in sorted(expected):
        arr = arrays[key]
        if not isinstance(arr, np.ndarray):
            raise ModelFileError(f"Behavior-HMM array '{key}' is not an array")
        if arr.ndim != 1 or arr.dtype.kind not in "iu":
            raise ModelFileError(f"array '{key}' must be 1-D integers, got {arr.dtype} {arr.shape}")
        # unsigned values beyond 2**63 - 1 would wrap around to negative ones in int64
        if arr.size and (arr.min() < 0 or arr.max() > np.iinfo(np.int64).max):
            raise ModelFileError(f"array '{key}' has negative values or does not fit int64")
    vectors = {key: np.asarray(arrays[key], dtype=np.int64) for key in _VECTORS}
    sizes = {"N": int(vectors["pi_counts"].shape[0]), "M": int(arrays["C_indptr"].shape[0]) - 1}
    if sizes["N"] < 1 or sizes["M"] < 1:
        raise ModelFileError("the Behavior-HMM has no states or no observation categories")
    if sizes["N"] > MAX_DENSE_STATES:
        raise ModelFileError(
            f"{sizes['N']} states is more than a Behavior-HMM holds ({MAX_DENSE_STATES})"
        )
    if vectors["start_counts"].shape[0] != sizes["N"]:
        raise ModelFileError("arrays 'pi_counts' and 'start_counts' differ in length")
    tables: dict[str, csr_array] = {}
    for name, cols in _SPARSE_TABLES.items():
        indptr, indices, data = (
            np.asarray(arrays[f"{name}_{part}"], dtype=np.int64) for part in CSR_PARTS
        )
        rows = sizes["M"] if name == "C" else sizes["N"]
        if indptr.shape[0] != rows + 1:
            raise ModelFileError(f"array '{name}_indptr' must have {rows + 1} entries")
        problem = check_counts(indptr, indices, data, sizes[cols])
        if problem:
            raise ModelFileError(f"sparse table '{name}' {problem}")
        tables[name] = csr_array((data, indices, indptr), shape=(rows, sizes[cols]))
    if not np.array_equal(tables["B"].sum(axis=1), vectors["pi_counts"]):
        raise ModelFileError("the emission counts 'B' do not add up to 'pi_counts'")
    if not self_transitions:
        for name in ("A", "C"):
            if np.any(tables[name].diagonal()):
                raise ModelFileError(
                    f"table '{name}' counts self transitions, which the parameters exclude"
                )
    return {
        **tables,
        "pi": vectors["pi_counts"],
        "start_prob_first": vectors["start_counts"],
    }
