"""Name → implementation registry over ``importlib.metadata`` entry points.

Every robot, filter, p-function, backend, trajectory and limit, built-in or third
party, is found the same way: an entry point in one of the groups below. A
third-party package adds, in its ``pyproject.toml``::

    [project.entry-points."otmm_qp.backends"]
    my_backend = "my_package.module:MyBackend"

Each loaded object is validated against its interface when it is first looked
up: a class must subclass the group's base class and implement its abstract
methods; a p-function must be a callable taking ``(s, sigma_s)``. Two
distributions claiming one name raise :class:`PluginValidationError`.
"""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from importlib import metadata
from typing import Any

from otmm_qp.exceptions import (
    ConfigError,
    OtmmError,
    ParameterError,
    PeerUnavailable,
    PluginNotFound,
    PluginValidationError,
    shown,
)
from otmm_qp.migration.keywords import from_config
from otmm_qp.migration.versions import gone_keys

ROBOTS = "otmm_qp.robots"
FILTERS = "otmm_qp.filters"
P_FUNCTIONS = "otmm_qp.p_functions"
BACKENDS = "otmm_qp.backends"
TRAJECTORIES = "otmm_qp.trajectories"
TASK_GENERATORS = "otmm_qp.task_generators"
LIMITS = "otmm_qp.limits"
PLANTS = "otmm_qp.plants"
CONDITIONING = "otmm_qp.conditioning"
GROUPS = (
    ROBOTS,
    FILTERS,
    P_FUNCTIONS,
    BACKENDS,
    TRAJECTORIES,
    TASK_GENERATORS,
    LIMITS,
    PLANTS,
    CONDITIONING,
)


@dataclass(frozen=True)
class EntryPointSpec:
    """Where a plugin comes from.

    Attributes:
        group: Entry-point group.
        name: Registered name.
        value: ``module:attribute`` target.
        distribution: Name of the distribution that registered it.
    """

    group: str
    name: str
    value: str
    distribution: str


_cache: dict[tuple[str, str], Any] = {}


#: The base class of each group, by import path (``module:Class``): the base modules import
#: this one, so the registry names them instead of importing them (no package cycle).
BASE_CLASSES: dict[str, str] = {
    ROBOTS: "otmm_qp.robots.robot:Robot",
    FILTERS: "otmm_qp.filters.task_filter:TaskFilter",
    BACKENDS: "otmm_qp.backends.backend:Backend",
    TRAJECTORIES: "otmm_qp.trajectories.trajectory:Trajectory",
    TASK_GENERATORS: "otmm_qp.scenarios.generator:TaskGenerator",
    LIMITS: "otmm_qp.limits.limit:BaseLimit",
    PLANTS: "otmm_qp.plants.plant:Plant",
    CONDITIONING: "otmm_qp.conditioning.stage:CommandStage",
}


def _base_class(group: str) -> type | None:
    """The base class a plugin of ``group`` must derive from (None: any object)."""
    path = BASE_CLASSES.get(group)
    if path is None:
        return None
    module, name = path.split(":")
    base: type = getattr(importlib.import_module(module), name)
    return base


def specs(group: str) -> dict[str, EntryPointSpec]:
    """Registered plugins of a group, by name.

    Raises:
        PluginValidationError: Two distributions register the same name.
    """
    found: dict[str, EntryPointSpec] = {}
    for entry in metadata.entry_points(group=group):
        dist = entry.dist.name if entry.dist is not None else "?"
        spec = EntryPointSpec(group, entry.name, entry.value, dist)
        previous = found.get(entry.name)
        if previous is not None and previous.value != spec.value:
            raise PluginValidationError(
                entry.name,
                f"name registered twice in {group}: {previous.value} "
                f"(from {previous.distribution}) and {spec.value} (from {dist})",
            )
        found[entry.name] = spec
    return dict(sorted(found.items()))


def available(group: str) -> list[str]:
    """Sorted names registered in ``group``."""
    return list(specs(group))


def validate(group: str, name: str, obj: Any) -> None:
    """Check that ``obj`` implements the interface of ``group``.

    Raises:
        PluginValidationError: Naming the plugin and what is missing.
    """
    base = _base_class(group)
    if base is None:  # p-functions: plain callables p(s, sigma_s, **params)
        if not callable(obj):
            raise PluginValidationError(name, "p-function must be callable as p(s, sigma_s)")
        params = list(inspect.signature(obj).parameters)
        if len(params) < 2:
            raise PluginValidationError(name, "p-function must accept (s, sigma_s)")
        return
    if not (inspect.isclass(obj) and issubclass(obj, base)):
        raise PluginValidationError(
            name, f"must be a subclass of {base.__module__}.{base.__name__}"
        )
    missing = sorted(getattr(obj, "__abstractmethods__", ()))
    if missing:
        raise PluginValidationError(name, f"does not implement {', '.join(missing)}")


def load(group: str, name: str) -> Any:
    """Load and validate the plugin ``name`` of ``group``.

    Raises:
        PluginNotFound: Listing the available names.
        PluginValidationError: The plugin fails its interface check or cannot be imported.
    """
    key = (group, name)
    if key in _cache:
        return _cache[key]
    registered = specs(group)
    if name not in registered:
        raise PluginNotFound(group, name, registered)
    entry = next(e for e in metadata.entry_points(group=group) if e.name == name)
    try:
        obj = entry.load()
    except SystemExit as stop:  # a plugin's import ending the program is its failure too
        raise PluginValidationError(
            name, f"cannot be loaded from {entry.value}: its import called sys.exit({stop.code!r})"
        ) from None
    except Exception as error:  # noqa: BLE001 - report any import failure as the plugin's fault
        raise PluginValidationError(
            name, f"cannot be loaded from {entry.value}: {error}"
        ) from error
    validate(group, name, obj)
    _cache[key] = obj
    return obj


def clear_cache() -> None:
    """Forget loaded plugins (after installing or patching entry points)."""
    _cache.clear()


def check_parameters(
    factory: Callable[..., Any],
    params: Mapping[str, Any],
    field: str,
    reserved: tuple[str, ...] = (),
    explained: Mapping[str, str] | None = None,
) -> None:
    """Reject parameters that ``factory`` does not accept, before calling it.

    Args:
        factory: Plugin class or function.
        params: Parameters from the config.
        field: Config path used in the message.
        reserved: Parameters the framework passes itself (hidden from the user).
        explained: Older keys → what to write with the user's own values
            (:func:`otmm_qp.migration.versions.gone_keys`), preferred to ``removed_parameters``.

    A plugin's ``removed_parameters`` (old name → one line saying what to write instead, e.g.
    a rename) are refused with that line rather than as unknown, all of them at once.

    Raises:
        ConfigError: Naming the unknown parameter and the allowed ones, or a required
            parameter that is missing.
        ParameterError: A removed parameter, with its replacement.
    """
    signature = inspect.signature(factory)
    accepted = [
        p.name
        for p in signature.parameters.values()
        if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and p.name not in ("self",)
    ]
    if any(p.kind == p.VAR_KEYWORD for p in signature.parameters.values()):
        return
    allowed = [a for a in accepted if a not in reserved]
    removed = {**(getattr(factory, "removed_parameters", None) or {}), **(explained or {})}
    gone = [key for key in params if key in removed and key not in allowed]
    if gone:  # renamed or removed: say what to write, for every such key at once
        rest = [f"{field}.{key}: {removed[key]}" for key in gone[1:]]
        raise ParameterError(f"{field}.{gone[0]}", removed[gone[0]], rest)
    required = [
        p.name
        for p in signature.parameters.values()
        if p.name in allowed and p.default is p.empty and p.name not in params
    ]
    if required:
        names = ", ".join(required)
        raise ConfigError(f"{field}.{required[0]}", f"required parameter missing (give {names})")
    for key in params:
        if key not in allowed:
            raise ConfigError(
                f"{field}.{key}", f"unknown parameter; allowed: {', '.join(allowed) or '(none)'}"
            )


def blame_parameter(
    factory: Callable[..., Any], params: Mapping[str, Any]
) -> tuple[str, str] | None:
    """The first parameter whose value does not fit ``factory``'s type hint, and why.

    Used when a plugin raised a bare TypeError/ValueError (``could not convert string to
    float``), so the message names the parameter and what it accepts. Hints pydantic cannot
    check (arrays, callables) are skipped.

    Returns:
        ``(name, "input should be ..., got VALUE")``, or None when every value fits its hint
        (or none is checkable).
    """
    import typing

    from pydantic import ConfigDict, TypeAdapter, ValidationError

    target = factory.__init__ if inspect.isclass(factory) else factory
    try:
        hints = typing.get_type_hints(target)
    except Exception:  # noqa: BLE001 - unresolvable hints: nothing to blame
        return None
    for key, value in params.items():
        hint = hints.get(key)
        if hint is None:
            continue
        try:
            adapter: TypeAdapter[Any] = TypeAdapter(
                hint, config=ConfigDict(arbitrary_types_allowed=True)
            )
        except Exception:  # noqa: BLE001 - a hint pydantic cannot express
            continue
        try:
            adapter.validate_python(value)
        except ValidationError as error:
            first = error.errors()[0]
            where = "".join(f"[{p}]" for p in first["loc"] if isinstance(p, int))
            message = str(first["msg"]).split(",")[0]
            message = message[:1].lower() + message[1:]
            return (f"{key}{where}", f"{message}, got {shown(first.get('input', value))}")
        except Exception:  # noqa: BLE001 - arbitrary types: not checkable
            continue
    return None


def create(group: str, name: str, params: Mapping[str, Any], field: str, **framework: Any) -> Any:
    """Instantiate plugin ``name`` with user ``params`` plus framework-supplied keywords.

    Raises:
        PluginNotFound: Unknown name (listing available ones).
        ConfigError: Unknown or invalid parameter, with its config path.
    """
    try:
        factory = load(group, name)
    except PluginNotFound as error:
        raise ConfigError(field, str(error)) from error
    explained = gone_keys(group.rsplit(".", 1)[-1], {**params, "type": name})
    check_parameters(factory, params, field, tuple(framework), explained)
    try:
        with from_config():  # the file's schema is checked: no warning of a changed meaning
            return factory(**framework, **params)
    except ConfigError as error:
        if error.field.startswith(field):
            raise
        raise type(error)(
            f"{field}.{error.field}" if error.field else field, error.message
        ) from error
    except (TypeError, ValueError) as error:
        culprit = blame_parameter(factory, params)
        if culprit is not None:
            raise ConfigError(f"{field}.{culprit[0]}", culprit[1]) from None
        raise ConfigError(field, f"invalid parameters for {name!r}: {error}") from error
    except PeerUnavailable:
        raise  # not bad input: the runner reports the controller as skipped
    except OtmmError as error:  # e.g. SolverNotFound, FrameNotFound: keep the message, add the path
        raise ConfigError(field, str(error)) from error
