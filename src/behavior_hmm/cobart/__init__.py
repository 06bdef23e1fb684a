"""CobART: unsupervised categories of windows of readings (thesis §3.2).

``CobART`` categorizes filtered, normalized sensor data (episodes concatenated, with
``lengths``) into motion primitives or observation categories, one category per time
step; ``CobART.stream()`` gives a :class:`LiveCategorizer` for one reading at a time;
``HierarchicalCobART`` joins several first-layer networks through a relation network
(thesis §3.2.1). ``edm_similarity`` / ``dcm_similarity`` / ``cobart_score`` are the
matching functions.
"""

from behavior_hmm.cobart._cobart import (
    MOTION_PRIMITIVE_PARAMS,
    OBSERVATION_PARAMS,
    Categorization,
    CobART,
)
from behavior_hmm.cobart._hierarchical import HierarchicalCobART
from behavior_hmm.cobart._live import LiveCategorizer
from behavior_hmm.cobart._sequences import primitive_sequence, transition_counts
from behavior_hmm.cobart._similarity import (
    DEFAULT_DCM_SCALE,
    DEFAULT_EDM_SCALE,
    cobart_score,
    dcm_similarity,
    edm_similarity,
    suggest_dcm_scale,
)

__all__ = [
    "DEFAULT_DCM_SCALE",
    "DEFAULT_EDM_SCALE",
    "MOTION_PRIMITIVE_PARAMS",
    "OBSERVATION_PARAMS",
    "Categorization",
    "CobART",
    "HierarchicalCobART",
    "LiveCategorizer",
    "cobart_score",
    "dcm_similarity",
    "edm_similarity",
    "primitive_sequence",
    "suggest_dcm_scale",
    "transition_counts",
]
