"""Joint-space secondary tasks for the backends that resolve redundancy.

A backend parameter ``secondary: {type: NAME, **params}`` selects one (see
:func:`secondary_task_from`); the names are :data:`SECONDARY_TASKS`.
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping
from typing import Any

from otmm_qp.exceptions import ConfigError, ParameterError

from .joint_limits import JointLimitTask, limit_distance_gradient
from .posture import PostureTask
from .secondary_task import SecondaryTask

#: The secondary tasks by YAML name.
SECONDARY_TASKS: dict[str, type[SecondaryTask]] = {
    "joint_limits": JointLimitTask,
    "posture": PostureTask,
}


def secondary_task_from(spec: SecondaryTask | Mapping[str, Any] | None) -> SecondaryTask | None:
    """Build the secondary task of a ``secondary: {type: NAME, ...}`` block (or pass one through).

    Raises:
        ConfigError: Not a mapping, no or an unknown ``type``, or an unknown parameter — one
            line naming ``secondary.<field>`` and what is allowed.
        ParameterError: A value its declared constraints refuse (``secondary.<field>``).
    """
    if spec is None or isinstance(spec, SecondaryTask):
        return spec
    if not isinstance(spec, Mapping):
        raise ConfigError("secondary", f"must be {{type: NAME, ...}}, got {spec!r:.40}")
    params = dict(spec)
    kind = params.pop("type", None)
    if kind not in SECONDARY_TASKS:
        raise ConfigError(
            "secondary.type",
            f"unknown secondary task {kind!r:.40}; available: {', '.join(sorted(SECONDARY_TASKS))}",
        )
    cls = SECONDARY_TASKS[kind]
    allowed = [p for p in inspect.signature(cls.__init__).parameters if p != "self"]
    for key in params:
        if key not in allowed:
            raise ConfigError(
                f"secondary.{key}",
                f"unknown parameter of {kind!r}; allowed: {', '.join(allowed)}",
            )
    try:
        return cls(**params)
    except ParameterError as error:
        raise ParameterError(f"secondary.{error.field}", error.message) from None


__all__ = [
    "SECONDARY_TASKS",
    "JointLimitTask",
    "PostureTask",
    "SecondaryTask",
    "limit_distance_gradient",
    "secondary_task_from",
]
