"""One estimator base: scikit-learn style parameters, ``repr``, ``clone`` and the fitted check.

An estimator's parameters are the arguments of its ``__init__``, which stores each of
them unchanged in an attribute of the same name and does nothing else (values are
checked by ``fit``). What ``fit`` learns is stored in attributes whose names end in
``_``. :class:`Estimator` derives ``get_params``, ``set_params`` and ``__repr__`` from
the ``__init__`` signature, as :class:`sklearn.base.BaseEstimator` does.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Sequence
from typing import Any, Self, TypeVar

from behavior_hmm.errors import ConfigError, NotFittedError

E = TypeVar("E", bound="Estimator")

# class -> its parameters (name -> default, ``inspect.Parameter.empty`` if required)
_SIGNATURES: dict[type, dict[str, Any]] = {}


class Estimator:
    """Base of the estimators: ``get_params`` / ``set_params`` / ``repr`` from ``__init__``.

    Parameters whose value is itself an :class:`Estimator` are nested: ``get_params()``
    adds their parameters as ``name__param``, and ``set_params(name__param=value)``
    reaches into them.
    """

    @classmethod
    def _param_defaults(cls) -> dict[str, Any]:
        """Parameter name -> default value (``inspect.Parameter.empty`` if it has none)."""
        table = _SIGNATURES.get(cls)
        if table is None:
            sig = inspect.signature(cls.__init__)
            table = {
                name: p.default
                for name, p in sig.parameters.items()
                if name != "self" and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
            }
            _SIGNATURES[cls] = table
        return table

    @classmethod
    def _param_names(cls) -> tuple[str, ...]:
        """Names of the ``__init__`` parameters, in signature order."""
        return tuple(cls._param_defaults())

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """Parameters by name; ``deep`` adds ``name__param`` for nested estimators."""
        out: dict[str, Any] = {}
        for name in self._param_names():
            value = getattr(self, name)
            out[name] = value
            if deep and isinstance(value, Estimator):
                for sub, sub_value in value.get_params(deep=True).items():
                    out[f"{name}__{sub}"] = sub_value
        return out

    def set_params(self, **params: Any) -> Self:
        """Set parameters by name (``name__param`` for a nested estimator); returns ``self``.

        Values take effect at the next ``fit`` (they are checked there).

        Raises
        ------
        ConfigError
            A name that is not a parameter, naming the class and its parameters.
        """
        names = self._param_names()
        nested: dict[str, dict[str, Any]] = {}
        for key in params:
            head, sep, rest = key.partition("__")
            if head not in names:
                raise ConfigError(_unknown_message(type(self), key, names))
            if sep:
                nested.setdefault(head, {})[rest] = params[key]
        for key, value in params.items():
            if "__" not in key:
                setattr(self, key, value)
        for head, sub in nested.items():
            inner = getattr(self, head)
            if not isinstance(inner, Estimator):
                raise ConfigError(
                    f"parameter '{head}' of {type(self).__name__} is "
                    f"{type(inner).__name__}, not an estimator: it has no sub-parameters"
                )
            try:
                inner.set_params(**sub)
            except ConfigError as err:
                raise ConfigError(f"{type(self).__name__}.{head}: {err}") from None
        if params:
            self._params_changed()
        return self

    def _params_changed(self) -> None:
        """Hook called by :meth:`set_params` after it changed parameters (default: nothing).

        Override to drop what was derived from the old values, e.g. caches of a fitted model.
        """

    def __repr__(self) -> str:
        """Class name and the parameters that differ from their defaults (scikit-learn style)."""
        defaults = self._param_defaults()
        parts = [
            f"{name}={value!r}"
            for name, value in self.get_params(deep=False).items()
            if _changed(value, defaults[name])
        ]
        return f"{type(self).__name__}({', '.join(parts)})"


def clone(estimator: E) -> E:
    """A new unfitted estimator of the same class with the same parameters.

    Parameters that are estimators are cloned too (so they come unfitted); every other
    value is passed on as it is (estimators never modify their parameters), so fitted
    models given as data, e.g. a CBLM's ``components``, stay fitted and shared.

    Raises
    ------
    ConfigError
        ``estimator`` is not an :class:`Estimator`.
    """
    if not isinstance(estimator, Estimator):
        raise ConfigError(f"cannot clone {type(estimator).__name__}: it is not an Estimator")
    params = {
        name: clone(value) if isinstance(value, Estimator) else value
        for name, value in estimator.get_params(deep=False).items()
    }
    return type(estimator)(**params)


def is_fitted(estimator: Any, attributes: str | Sequence[str] | None = None) -> bool:
    """Whether ``fit`` has run: every name in ``attributes`` is set, or by default any
    learned attribute (a public name ending in ``_``) is."""
    if attributes is None:
        names = getattr(estimator, "__dict__", {})
        return any(n.endswith("_") and not n.startswith("_") for n in names)
    wanted = (attributes,) if isinstance(attributes, str) else tuple(attributes)
    # a learned property of an unfitted model raises NotFittedError, an AttributeError
    return all(hasattr(estimator, name) for name in wanted)


def check_is_fitted(estimator: Any, attributes: str | Sequence[str] | None = None) -> None:
    """Raise :class:`~behavior_hmm.errors.NotFittedError` unless :func:`is_fitted`."""
    if not is_fitted(estimator, attributes):
        raise NotFittedError(f"this {type(estimator).__name__} is not fitted yet; call fit first")


def _unknown_message(cls: type, key: str, names: Sequence[str]) -> str:
    valid = f"valid parameters: {', '.join(names)}" if names else "it has no parameters"
    return f"unknown parameter '{key}' for {cls.__name__}; {valid}"


def _changed(value: Any, default: Any) -> bool:
    """Whether ``value`` differs from the constructor default (what ``repr`` shows)."""
    if default is inspect.Parameter.empty:
        return True
    if value is default:
        return False
    if type(value) is not type(default):
        return True
    if isinstance(value, float) and math.isnan(value) and math.isnan(default):
        return False
    try:
        return not bool(value == default)
    except (TypeError, ValueError):  # e.g. arrays: their == is elementwise
        return repr(value) != repr(default)
