"""Keyword arguments, attributes and file keys of release 0.2 that were renamed, kept for one release.

One concept has one name across the command line, Python and files (docs/reference/architecture.md,
"Names"). Where an old name was public it keeps working until 0.3 with a :class:`DeprecationWarning`:

* :func:`renamed_fields` on a dataclass: the old keyword of its constructor (and so of
  :func:`dataclasses.replace`) gives the new field, and reading the old attribute gives the new one.
* :func:`renamed_keyword` on a function: the old keyword gives the new parameter.
* :func:`renamed_keys`: a mapping read from a file written before the rename, with its old keys
  under their new names (no warning: old files stay readable without a word).

This module imports nothing of the package; it is a foundation every stage may use.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable, Mapping
from typing import Any, TypeVar

__all__ = [
    "RENAMED_KEYS",
    "renamed_fields",
    "renamed_keys",
    "renamed_keyword",
]

T = TypeVar("T")
F = TypeVar("F", bound=Callable[..., Any])

#: Old key -> new key of the settings and results files written before the renames.
RENAMED_KEYS: dict[str, str] = {
    "iterations": "expansions",
    "trajectories": "n_trajectories",
    "frames": "n_frames",
    "ablation_trajectories": "ablation_n_trajectories",
    "ablation_frames": "ablation_n_frames",
}


def _warn(owner: str, old: str, new: str) -> None:
    warnings.warn(f"{owner}: {old!r} is now {new!r}; the old name goes in 0.3", DeprecationWarning, stacklevel=4)


def renamed_fields(**renames: str) -> Callable[[type[T]], type[T]]:
    """Class decorator: old keyword ``old=`` of the constructor and attribute ``.old`` give field ``new``.

    ``@renamed_fields(iterations="expansions")`` on a dataclass with an ``expansions`` field: both
    ``Config(iterations=5)`` and ``config.iterations`` still work and warn. The old keyword wins
    over the new one, so ``dataclasses.replace(config, iterations=5)`` (which also passes every
    field by its new name) changes the field.
    """

    def decorate(cls: type[T]) -> type[T]:
        init = cls.__init__

        @functools.wraps(init)
        def init_accepting_old_names(self: Any, *args: Any, **kwargs: Any) -> None:
            for old, new in renames.items():
                if old in kwargs:
                    _warn(cls.__name__, old, new)
                    kwargs[new] = kwargs.pop(old)
            init(self, *args, **kwargs)

        cls.__init__ = init_accepting_old_names  # type: ignore[method-assign]
        for old, new in renames.items():
            setattr(cls, old, property(_old_attribute(cls.__name__, old, new), doc=f"Deprecated: :attr:`{new}`."))
        return cls

    return decorate


def _old_attribute(owner: str, old: str, new: str) -> Callable[[Any], Any]:
    def read(self: Any) -> Any:
        warnings.warn(f"{owner}.{old} is now {owner}.{new}; the old name goes in 0.3", DeprecationWarning, stacklevel=2)
        return getattr(self, new)

    return read


def renamed_keyword(**renames: str) -> Callable[[F], F]:
    """Function decorator: the old keyword ``old=`` gives parameter ``new``, with a warning."""

    def decorate(function: F) -> F:
        @functools.wraps(function)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            for old, new in renames.items():
                if old in kwargs:
                    if new in kwargs:
                        raise TypeError(f"{function.__name__}() got both {old!r} and its new name {new!r}")
                    _warn(f"{function.__name__}()", old, new)
                    kwargs[new] = kwargs.pop(old)
            return function(*args, **kwargs)

        return wrapper  # type: ignore[return-value]

    return decorate


def renamed_keys(values: Mapping[str, Any], renames: Mapping[str, str] = RENAMED_KEYS) -> dict[str, Any]:
    """``values`` with each old key under its new name (a new key already present wins)."""
    out = dict(values)
    for old, new in renames.items():
        if old in out:
            value = out.pop(old)
            out.setdefault(new, value)
    return out
