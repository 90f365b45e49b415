"""The table of changes for Python callers: old keywords of a plugin's constructor.

:data:`~otmm_qp.migration.changes.CHANGES` speaks for the YAML (``run`` refuses,
``migrate`` rewrites) and, through :func:`check_keywords`, for the constructors: a keyword that
no longer exists (``QpBackend(limit_gain=0.5)``) raises a :class:`TypeError` naming its
replacement with the caller's values (``limits=[{'type': 'position', 'gain': 0.5}]``); a
keyword whose meaning changed (the QP family's ``damping``: μ in schema 1, λ since schema 2)
warns with :class:`~otmm_qp.exceptions.SchemaChangeWarning` (a ``FutureWarning``) and the value
it would have meant, for one release. A plugin built from a config file (:func:`from_config`,
entered by the registry) is not warned: the loader has already read the file's schema.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any

from otmm_qp.exceptions import SchemaChangeWarning
from otmm_qp.migration.changes import CHANGES, RELEASES, SchemaChange

__all__ = ["check_keywords", "from_config", "warn_changed"]

_FROM_CONFIG: ContextVar[bool] = ContextVar("otmm_qp_from_config", default=False)


@contextmanager
def from_config() -> Iterator[None]:
    """Plugins built inside are built from a config file whose schema was checked."""
    token = _FROM_CONFIG.set(True)
    try:
        yield
    finally:
        _FROM_CONFIG.reset(token)


def _python(change: SchemaChange, block: Mapping[str, Any]) -> str:
    """The keywords to write instead, with the caller's values (``regularization=0.0001``)."""
    after = change.convert(dict(block))
    changed = [k for k in after if k not in block or after[k] != block[k]]
    return ", ".join(f"{key}={after[key]!r}" for key in changed)


def check_keywords(
    group: str, kind: str, owner: str, accepted: frozenset[str], kwargs: Mapping[str, Any]
) -> list[str]:
    """Refuse an old keyword; say what a keyword whose meaning changed meant (the table's rows).

    Args:
        group: The registry group, last part (``backends``).
        kind: The plugin type (``qp``).
        owner: The class, for the message (``QpBackend``).
        accepted: The keywords the constructor takes today.
        kwargs: The keywords given.

    Returns:
        For each keyword whose meaning changed, what it meant then and what to write for
        that (nothing when built from a config file): the constructor warns them
        (:func:`warn_changed`) once it has accepted the values.

    Raises:
        TypeError: A keyword that no longer exists, naming what to write instead.
    """
    block = {**kwargs, "type": kind}
    changed = []
    for change in CHANGES:
        if change.key not in kwargs or not change.concerns(group, block):
            continue
        since = f"schema {change.version} ({RELEASES[change.version]})"
        if change.kind == "name" and change.key not in accepted:
            raise TypeError(
                f"{owner}() got an old keyword argument {change.key!r}: {change.now} since "
                f"{since}; write {_python(change, block)}"
            )
        if change.kind == "value" and not _FROM_CONFIG.get():
            before = RELEASES[change.version - 1]
            also = f" (or {change.also(block)})" if change.also is not None else ""
            changed.append(
                f"{owner}({change.key}={kwargs[change.key]!r}): in {before} this meant "
                f"{change.was}; since {RELEASES[change.version]} {change.key} means "
                f"{change.now}. To mean what it meant then, write {_python(change, block)}"
                f"{also} (warned for one release)"
            )
    return changed


def warn_changed(messages: list[str], stacklevel: int = 3) -> None:
    """Warn each message of :func:`check_keywords` as a :class:`SchemaChangeWarning`."""
    for message in messages:
        warnings.warn(message, SchemaChangeWarning, stacklevel=stacklevel)
