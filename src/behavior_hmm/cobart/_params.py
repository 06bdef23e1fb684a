"""scikit-learn style parameter handling (``get_params`` / ``set_params`` / ``repr``).

The CobART estimators use the package's one estimator base; ``ParamsMixin`` is its
name here.
"""

from __future__ import annotations

from behavior_hmm._estimator import Estimator

ParamsMixin = Estimator

__all__ = ["ParamsMixin"]
