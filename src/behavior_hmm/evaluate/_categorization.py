"""Thesis §6.1: categorize turn demonstrations into motion primitives (table 6.1, figs 6.1-6.4).

It runs in the calling process, not through the project's executor: its only independent
work, one CobART fit per vigilance, takes well under a second (0.2 s for both on the
default turn grid), less than starting worker processes.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Final

import numpy as np

from behavior_hmm.cobart import CobART, primitive_sequence, transition_counts
from behavior_hmm.data import Dataset, SignalPipeline
from behavior_hmm.models import preset_params

#: Starts whose primitive sequences the thesis lists in table 6.1 (degrees).
TABLE_6_1_STARTS: Final[tuple[float, ...]] = (-115.0, -168.0, 86.0, 123.0)
#: Vigilances of the thesis's two categorization experiments (figs 6.1/6.2 and 6.3/6.4).
RHOS: Final[tuple[float, ...]] = (0.85, 0.75)


def _common_suffix(a: Sequence[int], b: Sequence[int]) -> list[int]:
    out: list[int] = []
    for x, y in zip(reversed(a), reversed(b), strict=False):
        if x != y:
            break
        out.append(x)
    return out[::-1]


def run_categorization_experiment(
    train: Dataset,
    samples: Dataset,
    *,
    rhos: Sequence[float] = RHOS,
    inputs: Sequence[str] = ("angle",),
) -> dict[str, Any]:
    """Categorize turn demonstrations into motion primitives at several vigilances.

    Parameters
    ----------
    train
        Turn demonstrations (the default grid) that CobART learns from.
    samples
        Demonstrations from the table 6.1 starts, categorized without learning.
    rhos
        Vigilances to compare.

    Returns
    -------
    dict
        Per ``rho``: the number of primitives, per-step labels and start angles of the
        training episodes (for the angle-vs-category figure), the transition counts
        (transition diagram), the primitive sequence of each sample start (table 6.1),
        and the analysis: the shared tail of same-direction pairs and the primitives
        shared by opposite directions.
    """
    # a reproduction of the thesis's §6.1: filtered as in the thesis preset
    pipeline = SignalPipeline(tuple(inputs), preset_params("thesis", "SBLM")["cutoff_hz"])
    x_train = pipeline.transform(train)
    x_samples = pipeline.transform(samples)
    angle_train = train.column("angle")
    starts_train = [float(ep.sensors[0, 2]) for ep in train.episodes()]
    starts_samples = [float(ep.sensors[0, 2]) for ep in samples.episodes()]
    results: dict[str, Any] = {"inputs": list(inputs), "runs": []}
    for rho in rhos:
        net = CobART.motion_primitives(rho=rho).fit(x_train, train.lengths)
        labels = net.labels_
        counts = transition_counts(labels, train.lengths, net.n_categories_, collapse=True)
        sample_labels = net.predict(x_samples, samples.lengths)
        sequences: list[dict[str, Any]] = []
        for a, b, start in zip(
            samples.offsets[:-1], samples.offsets[1:], starts_samples, strict=True
        ):
            sequences.append({"start": start, "sequence": primitive_sequence(sample_labels[a:b])})
        same: list[dict[str, Any]] = []
        opposite: list[dict[str, Any]] = []
        for i in range(len(sequences)):
            for j in range(i + 1, len(sequences)):
                si, sj = sequences[i], sequences[j]
                a_i, a_j = float(si["start"]), float(sj["start"])
                pair = [a_i, a_j]
                if np.sign(a_i) == np.sign(a_j):
                    tail = _common_suffix(si["sequence"], sj["sequence"])
                    same.append({"starts": pair, "shared_tail": tail})
                else:
                    shared = sorted(set(si["sequence"]) & set(sj["sequence"]))
                    opposite.append({"starts": pair, "shared": shared})
        results["runs"].append(
            {
                "rho": rho,
                "n_primitives": int(net.n_categories_),
                "labels": labels.tolist(),
                "angles": angle_train.tolist(),
                "episode_starts": starts_train,
                "lengths": train.lengths.tolist(),
                "transitions": counts.tolist(),
                "sequences": sequences,
                "same_direction": same,
                "opposite_direction": opposite,
                "same_direction_share_tail": all(len(s["shared_tail"]) > 0 for s in same),
                "opposite_directions_share_none": all(not o["shared"] for o in opposite),
            }
        )
    return results
