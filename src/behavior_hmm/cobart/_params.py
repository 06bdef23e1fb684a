"""scikit-learn style parameter handling (``get_params`` / ``set_params`` / ``repr``)."""

from __future__ import annotations

import inspect
from typing import Any, Self

from behavior_hmm.errors import ConfigError


class ParamsMixin:
    """Parameters are the ``__init__`` arguments, stored unchanged under the same names."""

    @classmethod
    def _param_names(cls) -> list[str]:
        sig = inspect.signature(cls.__init__)
        return [
            name
            for name, p in sig.parameters.items()
            if name != "self" and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
        ]

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """Parameters of this estimator (``deep`` adds ``name__param`` of nested estimators)."""
        out: dict[str, Any] = {}
        for name in self._param_names():
            value = getattr(self, name)
            out[name] = value
            if deep and isinstance(value, ParamsMixin):
                for sub, sub_value in value.get_params(deep=True).items():
                    out[f"{name}__{sub}"] = sub_value
        return out

    def set_params(self, **params: Any) -> Self:
        """Set parameters by name; takes effect at the next ``fit``."""
        valid = set(self._param_names())
        for name, value in params.items():
            head, _, rest = name.partition("__")
            if head not in valid:
                raise ConfigError(
                    f"unknown parameter '{head}' for {type(self).__name__} "
                    f"(valid: {', '.join(sorted(valid))})"
                )
            if rest:
                nested = getattr(self, head)
                if not isinstance(nested, ParamsMixin):
                    raise ConfigError(f"parameter '{head}' has no sub-parameters")
                nested.set_params(**{rest: value})
            else:
                setattr(self, head, value)
        return self

    def __repr__(self) -> str:
        sig = inspect.signature(type(self).__init__)
        parts = []
        for name in self._param_names():
            value = getattr(self, name)
            default = sig.parameters[name].default
            if default is inspect.Parameter.empty or not _same(value, default):
                parts.append(f"{name}={value!r}")
        return f"{type(self).__name__}({', '.join(parts)})"


def _same(a: Any, b: Any) -> bool:
    try:
        return bool(a == b) and type(a) is type(b)
    except (TypeError, ValueError):
        return False
