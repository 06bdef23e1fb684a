"""Demonstrations and their left–right mirror images.

A robot whose left and right are alike (our Khepera: two wheels either side of its
axis) that was shown a turn to the left from 40° also knows, by symmetry, the turn to
the right from −40°: the same run with the bearing and the yaw rate negated and the
wheels' commands traded. :func:`mirrored` adds that image of every demonstration; how a
channel maps is declared once, with the channel (:attr:`ChannelSpec.mirror
<behavior_hmm.data.ChannelSpec>`: ``"even"``, ``"odd"`` or the channel it trades places
with). A model's ``mirror=True`` learns from both (docs/algorithms.md, "Mirror images").
"""

from __future__ import annotations

from typing import Any

import numpy as np

from behavior_hmm.data._channels import MIRROR_PARITIES, ChannelSpec
from behavior_hmm.data._dataset import Dataset
from behavior_hmm.data._units import wrap_degrees
from behavior_hmm.errors import ConfigError

#: Metadata key a mirrored dataset carries: ``true``.
MIRRORED_KEY = "mirrored"


def mirror_map(specs: list[ChannelSpec]) -> dict[str, str]:
    """Each channel's mirror (``"even"``, ``"odd"`` or its partner's name), checked.

    Raises
    ------
    ConfigError
        A channel that declares no mirror, a partner that is not among ``specs``, or a
        pair that does not name each other.
    """
    by_name = {spec.name: spec for spec in specs}
    out: dict[str, str] = {}
    for spec in specs:
        image = spec.mirror
        if image is None:
            raise ConfigError(
                f"channel '{spec.name}' declares no mirror image, so its demonstrations "
                "cannot be mirrored: declare its 'mirror' ('even', 'odd' or the channel it "
                "trades places with) in the channel's declaration, or leave mirror off"
            )
        if image not in MIRROR_PARITIES:
            partner = by_name.get(image)
            if partner is None:
                raise ConfigError(
                    f"channel '{spec.name}' mirrors onto '{image}', which these "
                    "demonstrations do not hold"
                )
            if partner.mirror != spec.name:
                raise ConfigError(
                    f"channel '{spec.name}' mirrors onto '{image}', but '{image}' mirrors "
                    f"onto {partner.mirror!r}: a pair must name each other"
                )
        out[spec.name] = image
    return out


def mirrored(dataset: Dataset) -> Dataset:
    """Every demonstration followed by its left–right mirror image.

    The image of an episode negates its odd channels (an angle is wrapped back into
    (−180, 180]: −180 stays 180), keeps its even ones and trades the values of each
    declared pair (the wheels' commands); time and the ``behavior`` tags are the
    original's. Episodes are renumbered in order, the original ``2 i`` and its image
    ``2 i + 1`` (``i`` its position), so fitting two datasets one after the other sees
    the episodes in the order fitting their concatenation does. The metadata's
    ``corrective_episodes`` follow the renumbering (an image of a corrective run is
    one too), and ``mirrored`` is set.

    Parameters
    ----------
    dataset
        Demonstrations whose every sensor and command channel declares its mirror.

    Returns
    -------
    Dataset
        Twice the episodes.

    Raises
    ------
    ConfigError
        A channel without a mirror (:func:`mirror_map`), or a dataset already mirrored.
    """
    meta = dataset.metadata
    if meta.get(MIRRORED_KEY):
        raise ConfigError("these demonstrations are already mirrored")
    specs = dataset.channel_specs
    images = mirror_map([*specs, *dataset.command_specs])
    wraps = {spec.name for spec in (*specs, *dataset.command_specs) if spec.wraps}
    cols = dataset.to_columns()
    image: dict[str, Any] = {}
    for name, value in cols.items():
        kind = images.get(name)
        if kind is None or kind == "even":
            image[name] = value
        elif kind == "odd":
            flipped = -np.asarray(value, dtype=np.float64)
            image[name] = wrap_degrees(flipped) if name in wraps else flipped
        else:
            image[name] = cols[kind]
    lengths = dataset.lengths
    n, total = len(lengths), dataset.n_samples
    starts = dataset.offsets[:-1]
    # episode i's rows, then its image's (the image's rows lie ``total`` further on)
    pairs = zip(starts, lengths, strict=True)
    rows = np.concatenate([np.arange(s, s + m) + k * total for s, m in pairs for k in (0, 1)])
    out = {
        name: np.concatenate([np.asarray(cols[name]), np.asarray(image[name])])[rows]
        for name in cols
    }
    out["episode"] = np.repeat(np.arange(2 * n, dtype=np.int64), np.repeat(lengths, 2))
    position = {int(eid): i for i, eid in enumerate(dataset.episode_ids)}
    corrective = meta.get("corrective_episodes")
    if corrective:
        meta["corrective_episodes"] = sorted(
            2 * position[int(e)] + k for e in corrective if int(e) in position for k in (0, 1)
        )
    meta[MIRRORED_KEY] = True
    return Dataset(out, meta)
