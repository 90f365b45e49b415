r"""Declared parameter constraints, checked once when a plugin is constructed.

Modelled on scikit-learn's ``sklearn/utils/_param_validation.py`` (own code): a plugin
declares what each constructor parameter accepts, and its ``__init__`` checks the values it
was given against the declarations before doing anything else::

    class MyBackend(Backend):
        parameter_constraints: ClassVar[Constraints] = {
            "damping": Interval(Real, 0, None, closed="left"),
            "policy": OneOf("raise", "hold"),
            "q_nominal": [ArrayOf(Interval(Real, None, None)), None],
        }

        def __init__(self, damping=0.05, policy="raise", q_nominal=None):
            check_params(self, locals())
            ...

A parameter's declaration is one :class:`Constraint`, ``None`` (the value ``None`` is
accepted) or a list of them (any one suffices). A value that satisfies none raises
:class:`~otmm_qp.exceptions.ParameterError` with one line: the field, the value given and what
is allowed (the ``describe()`` of each constraint). Real intervals refuse NaN and ±inf,
booleans are not numbers. Checks that relate parameters to each other (``max_gain ≥ 1/σ_S``,
``w0`` xor ``sigma_threshold``) stay explicit code in one place of the plugin; checks that
need the robot (a per-joint list of length ``nv``) happen at ``bind``.

A parameter that was renamed or removed is listed in the plugin's
``removed_parameters: ClassVar[Mapping[str, str]]`` (old name → one line saying what to write
instead); :func:`otmm_qp.registry.check_parameters` refuses it with that line.

``otmm-qp list --params`` shows the declarations (:func:`parameters`).
"""

from __future__ import annotations

import abc
import inspect
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from numbers import Integral, Real
from typing import Any, Literal, TypeVar

import numpy as np
import numpy.typing as npt

from otmm_qp.exceptions import DimensionError, ParameterError, shown

__all__ = [
    "ArrayOf",
    "Boolean",
    "Constraint",
    "Constraints",
    "InstanceOf",
    "Interval",
    "OneOf",
    "REQUIRED",
    "ParameterInfo",
    "RegisteredName",
    "check_params",
    "constraints_of",
    "declaration_problems",
    "declare",
    "describe",
    "parameters",
    "per_joint",
    "positive_per_joint",
    "signature_parameters",
]

Closed = Literal["left", "right", "both", "neither"]


class Constraint(abc.ABC):
    """What one parameter accepts."""

    @abc.abstractmethod
    def is_satisfied_by(self, value: object) -> bool:
        """Whether ``value`` is allowed."""

    @abc.abstractmethod
    def describe(self) -> str:
        """What is allowed, as the end of "must be ..." (e.g. ``a finite number > 0``)."""

    def __repr__(self) -> str:
        """The description, so a declaration prints readably."""
        return f"<{self.describe()}>"


#: One parameter's declaration: a constraint, ``None`` (the value None allowed) or a list.
ConstraintSpec = Constraint | None | Sequence[Constraint | None]
#: A plugin's declarations, by constructor parameter name.
Constraints = Mapping[str, ConstraintSpec]


def _finite_number(value: object) -> bool:
    """A real number (not a bool) that is neither NaN nor ±inf."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, Real):
        return False
    try:
        return math.isfinite(float(value))
    except OverflowError:  # an integer beyond the float range (10**400)
        return False


class Interval(Constraint):
    r"""A finite real (or integer) number in an interval; NaN, ±inf and booleans are refused.

    Args:
        kind: :class:`numbers.Real` or :class:`numbers.Integral` (integral floats such as
            ``2.0`` count as integers, as YAML may write them).
        low: Lower bound, or None (unbounded below).
        high: Upper bound, or None (unbounded above).
        closed: Which bounds belong to the interval: ``left`` (``low ≤ x``), ``right``
            (``x ≤ high``), ``both`` or ``neither``.
        unit: Unit shown by :meth:`describe`, e.g. ``rad/s``.
        inf_ok: Whether ``+inf`` is allowed too (meaning "unlimited"; only without ``high``).

    Raises:
        ValueError: ``kind`` is neither, a bound is not finite, or ``low > high``.
    """

    def __init__(
        self,
        kind: type[Real] | type[Integral],
        low: float | None,
        high: float | None,
        *,
        closed: Closed = "both",
        unit: str = "",
        inf_ok: bool = False,
    ) -> None:
        if kind not in (Real, Integral):
            raise ValueError(f"kind must be numbers.Real or numbers.Integral, got {kind!r}")
        for bound in (low, high):
            if bound is not None and not math.isfinite(bound):
                raise ValueError(f"bounds must be finite or None, got {bound!r}")
        if low is not None and high is not None and low > high:
            raise ValueError(f"low {low} > high {high}")
        self.kind = kind
        self.low = low
        self.high = high
        self.closed = closed
        self.unit = unit
        self.inf_ok = inf_ok and high is None

    def is_satisfied_by(self, value: object) -> bool:
        """Finite (or +inf where allowed), of the kind, and within the bounds."""
        if self.inf_ok and isinstance(value, float | np.floating) and value == math.inf:
            return True
        if not _finite_number(value):
            return False
        number = float(value)  # type: ignore[arg-type] # a Real, checked above
        if self.kind is Integral and not number.is_integer():
            return False
        left = self.closed in ("left", "both")
        right = self.closed in ("right", "both")
        if self.low is not None and not (number >= self.low if left else number > self.low):
            return False
        return self.high is None or (number <= self.high if right else number < self.high)

    def describe(self) -> str:
        """E.g. ``a finite number > 0``, ``in (0, 1]`` (finite implied), ``an integer >= 1``."""
        noun = "an integer" if self.kind is Integral else "a finite number"
        left = self.closed in ("left", "both")
        right = self.closed in ("right", "both")
        if self.low is not None and self.high is not None:
            interval = f"{'[' if left else '('}{self.low:g}, {self.high:g}{']' if right else ')'}"
            text = f"in {interval}" if self.kind is Real else f"{noun} in {interval}"
        elif self.low is not None:
            text = f"{noun} {'>=' if left else '>'} {self.low:g}"
        elif self.high is not None:
            text = f"{noun} {'<=' if right else '<'} {self.high:g}"
        else:
            text = noun
        text = f"{text} [{self.unit}]" if self.unit else text
        return f"{text} (inf: unlimited)" if self.inf_ok else text


class OneOf(Constraint):
    """One of a few fixed values (strings, numbers); a bool matches only a bool option.

    Args:
        *options: The allowed values.
    """

    def __init__(self, *options: object) -> None:
        if not options:
            raise ValueError("OneOf needs at least one option")
        self.options = options

    def is_satisfied_by(self, value: object) -> bool:
        """Equal to an option of the same kind (no array or container comparisons)."""
        if not isinstance(value, str | int | float | np.integer | np.floating):
            return False
        is_bool = isinstance(value, bool | np.bool_)
        return any(
            isinstance(option, bool) == is_bool and value == option for option in self.options
        )

    def describe(self) -> str:
        """E.g. ``'band' or 'moveit'``, ``one of 'raise', 'hold', 'dls'``."""
        shown = [repr(option) for option in self.options]
        if len(shown) <= 2:
            return " or ".join(shown)
        return f"one of {', '.join(shown)}"


class Boolean(Constraint):
    """``true`` or ``false`` (a Python or NumPy bool; 0 and 1 are refused)."""

    def is_satisfied_by(self, value: object) -> bool:
        """A bool."""
        return isinstance(value, bool | np.bool_)

    def describe(self) -> str:
        """``true or false``."""
        return "true or false"


class ArrayOf(Constraint):
    r"""A non-empty flat list of numbers, each satisfying ``element`` (or a scalar one).

    The per-joint / per-row form: the length against the robot (``nv``, the task dimension)
    is checked where the robot is known (``bind``); ``length`` fixes it up front.

    Args:
        element: The constraint on every entry (an :class:`Interval`, so NaN/inf refused).
        scalar: Whether one number is accepted too (meaning: the same for every entry).
        length: Required length, or None (any length ≥ 1).
        per: What one entry is for, shown by :meth:`describe` (e.g. ``joint``).
    """

    def __init__(
        self, element: Interval, *, scalar: bool = False, length: int | None = None, per: str = ""
    ) -> None:
        self.element = element
        self.scalar = scalar
        self.length = length
        self.per = per

    def is_satisfied_by(self, value: object) -> bool:
        """A scalar (if allowed) or a 1-D non-empty sequence whose entries all satisfy."""
        if isinstance(value, Real | np.number | np.bool_):  # NaN and ±inf too: the element judges
            return self.scalar and self.element.is_satisfied_by(value)
        if isinstance(value, str | bytes | Mapping) or not isinstance(value, Sequence | np.ndarray):
            return False
        array = np.asarray(value, dtype=object)
        if array.ndim != 1 or array.size == 0:
            return False
        if self.length is not None and array.size != self.length:
            return False
        return all(self.element.is_satisfied_by(entry) for entry in array)

    def describe(self) -> str:
        """E.g. ``a finite number > 0 or a list of them (one per joint)``."""
        count = f"{self.length} " if self.length is not None else ""
        per = f" (one per {self.per})" if self.per else ""
        if self.scalar:
            return f"{self.element.describe()} or a list of {count}them{per}"
        return f"a list of {count}entries, each {self.element.describe()}{per}"


class InstanceOf(Constraint):
    """An instance of one of ``types`` (e.g. a mapping ``{type: NAME, ...}``, a limit object).

    Args:
        types: Accepted classes.
        description: What to call them in messages, e.g. ``a mapping {type: NAME, ...}``.
        exclude: Classes refused even though they are instances of ``types`` (``str`` for
            ``Sequence``).
    """

    def __init__(
        self, types: tuple[type, ...], description: str, exclude: tuple[type, ...] = ()
    ) -> None:
        self.types = types
        self.description = description
        self.exclude = exclude

    def is_satisfied_by(self, value: object) -> bool:
        """``isinstance(value, types)`` and not of an excluded class."""
        return isinstance(value, self.types) and not isinstance(value, self.exclude)

    def describe(self) -> str:
        """The description given."""
        return self.description


class RegisteredName(Constraint):
    """The name of a registered plugin, e.g. a p-function.

    A string; whether it is registered is checked when it is loaded, by
    :class:`~otmm_qp.exceptions.PluginNotFound` listing the names.

    Args:
        group: Entry-point group, e.g. ``otmm_qp.p_functions``.
        what: What one is called in messages, e.g. ``p-function``.
    """

    def __init__(self, group: str, what: str) -> None:
        self.group = group
        self.what = what

    def is_satisfied_by(self, value: object) -> bool:
        """A string."""
        return isinstance(value, str)

    def describe(self) -> str:
        """E.g. ``a p-function name (bounded, cbrt, linear, power, sqrt)``."""
        from otmm_qp import registry  # lazily: the registry loads the plugins that import this

        return f"a {self.what} name ({', '.join(registry.available(self.group))})"


class _NoneConstraint(Constraint):
    """The value ``None`` (YAML ``null``), declared by writing ``None``."""

    def is_satisfied_by(self, value: object) -> bool:
        return value is None

    def describe(self) -> str:
        return "None"


def _options(spec: ConstraintSpec) -> list[Constraint]:
    """The constraints of one declaration, ``None`` turned into the None constraint."""
    items: Sequence[Constraint | None] = (
        [spec] if spec is None or isinstance(spec, Constraint) else spec
    )
    return [_NoneConstraint() if item is None else item for item in items]


def describe(spec: ConstraintSpec) -> str:
    """What a declaration allows, e.g. ``a finite number > 0 or None``."""
    return " or ".join(option.describe() for option in _options(spec))


def constraints_of(owner: object) -> Constraints | None:
    """The ``parameter_constraints`` of a class, instance or function (None: not declared)."""
    declared = getattr(owner, "parameter_constraints", None)
    return declared if isinstance(declared, Mapping) else None


def check_params(owner: object, params: Mapping[str, object]) -> None:
    """Check ``params`` against the declarations of ``owner``; call first in ``__init__``.

    Only declared names are checked (``locals()`` of ``__init__`` may be passed as is: ``self``
    and undeclared names are ignored). Cost: once per construction, never per step.

    Args:
        owner: The plugin (instance, class or p-function) that declares
            ``parameter_constraints``; nothing is checked when it declares none.
        params: Parameter values by name.

    Raises:
        ParameterError: ``field: must be <allowed>, got <value>`` for the first declared
            parameter whose value satisfies none of its constraints.
    """
    declared = constraints_of(owner)
    if declared is None:
        return
    for name, spec in declared.items():
        if name not in params:
            continue
        value = params[name]
        if not any(option.is_satisfied_by(value) for option in _options(spec)):
            raise ParameterError(name, f"must be {describe(spec)}, got {shown(value)}")


F = TypeVar("F", bound=Callable[..., Any])


def declare(
    constraints: Constraints, cross_check: Callable[..., None] | None = None
) -> Callable[[F], F]:
    """Decorator declaring the ``parameter_constraints`` of a function plugin (a p-function).

    Args:
        constraints: The declarations, by parameter name.
        cross_check: Optional check relating the parameters to each other or to the context
            (a p-function's: ``cross_check(sigma_s, **params)``), stored as ``cross_check``
            and run once by whoever builds the plugin, after :func:`check_params`.
    """

    def attach(function: F) -> F:
        function.parameter_constraints = constraints  # type: ignore[attr-defined]
        function.cross_check = cross_check  # type: ignore[attr-defined]
        return function

    return attach


#: The value of :attr:`ParameterInfo.default` for a parameter without default.
REQUIRED = "(required)"


@dataclass(frozen=True)
class ParameterInfo:
    """One user-facing constructor parameter of a plugin, for listings.

    Attributes:
        name: Parameter name.
        default: ``repr`` of the default, or :data:`REQUIRED`.
        allowed: What the declaration allows, or ``not declared``.
    """

    name: str
    default: str
    allowed: str


def signature_parameters(owner: object, reserved: Sequence[str] = ()) -> list[inspect.Parameter]:
    """The named parameters a config can give ``owner`` (a class's ``__init__``, a function).

    ``self``, ``*args``/``**kwargs`` and the ``reserved`` names the framework passes itself
    (a p-function's ``s, sigma_s``) are left out.
    """
    if inspect.isroutine(owner):
        target: Any = owner
    else:  # a class or an instance: its __init__
        target = (owner if inspect.isclass(owner) else type(owner)).__init__
    try:
        signature = inspect.signature(target)
    except (TypeError, ValueError):
        return []
    kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    return [
        p
        for p in signature.parameters.values()
        if p.kind in kinds and p.name != "self" and p.name not in reserved
    ]


def parameters(owner: object, reserved: Sequence[str] = ()) -> list[ParameterInfo]:
    """Each parameter of ``owner`` with its default and what it allows (for ``otmm-qp list``).

    Third-party plugins without declarations list their signature with ``not declared``.
    """
    declared = constraints_of(owner) or {}
    rows = []
    for p in signature_parameters(owner, reserved):
        default = REQUIRED if p.default is inspect.Parameter.empty else shown(p.default)
        allowed = describe(declared[p.name]) if p.name in declared else "not declared"
        rows.append(ParameterInfo(p.name, default, allowed))
    return rows


def declaration_problems(owner: object, reserved: Sequence[str] = ()) -> list[str]:
    """What is wrong with a plugin's declarations (empty: nothing), for its own tests.

    The declared names must be exactly the constructor's parameters (less ``reserved``), and
    every default must satisfy its declaration.

    Args:
        owner: The plugin class or function.
        reserved: Parameters the framework passes itself (a p-function's ``s, sigma_s``).

    Returns:
        One line per problem, e.g. ``declared but not a parameter: gian``.
    """
    declared = constraints_of(owner)
    if declared is None:
        return ["no parameter_constraints declared"]
    accepted = signature_parameters(owner, reserved)
    names = [p.name for p in accepted]
    problems = [f"declared but not a parameter: {n}" for n in declared if n not in names]
    problems += [f"parameter not declared: {n}" for n in names if n not in declared]
    for p in accepted:
        if p.name in declared and p.default is not inspect.Parameter.empty:
            try:
                check_params(owner, {p.name: p.default})
            except ParameterError as error:
                problems.append(f"default refused: {error}")
    return problems


def positive_per_joint(unit: str) -> ArrayOf:
    """A limit per joint: a number > 0 [``unit``] (inf: that joint unlimited) or one per joint.

    The declaration of every rate-type limit (accelerations, decelerations) beside
    :func:`per_joint`, which turns the value into an ``(nv,)`` array once the robot is known.
    """
    return ArrayOf(
        Interval(Real, 0, None, closed="neither", unit=unit, inf_ok=True), scalar=True, per="joint"
    )


def per_joint(
    value: float | Sequence[float] | npt.NDArray[np.float64] | None,
    name: str,
    nv: int,
) -> npt.NDArray[np.float64] | None:
    """A scalar or ``(nv,)`` parameter as an ``(nv,)`` float array (None stays None).

    Raises:
        DimensionError: ``value`` is neither a scalar nor of shape ``(nv,)``.
    """
    if value is None:
        return None
    array = np.asarray(value, dtype=float)
    if array.ndim == 0:
        array = np.full(nv, float(array))
    if array.shape != (nv,):
        raise DimensionError(name, (nv,), array.shape)
    return array
