r"""On-line Task Modification Method (OTMM), paper eq. (8), generalised to corank k."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from functools import partial
from numbers import Real
from typing import Any, ClassVar

import numpy as np

from otmm_qp import registry
from otmm_qp.exceptions import ConfigError, ParameterError
from otmm_qp.filters.task_filter import FilterOutput, FilterReport, TaskFilter
from otmm_qp.paper import SIGMA_S
from otmm_qp.robots.robot import FloatArray
from otmm_qp.state import KinematicState
from otmm_qp.validation import (
    Constraints,
    InstanceOf,
    Interval,
    OneOf,
    RegisteredName,
    check_params,
    constraints_of,
)

PFunction = Callable[[float, float], float]
#: σ_S when a config gives none (the paper's value).
DEFAULT_SIGMA_S = SIGMA_S
#: ``p``: the name of a registered p-function (which names exist is checked when loading).
P_NAME = RegisteredName(registry.P_FUNCTIONS, "p-function")
#: ``p_params``: the p-function's parameters, checked against its declarations.
P_PARAMS = InstanceOf((Mapping,), "a mapping of the p-function's parameters")


def p_function(name: str, params: Mapping[str, Any] | None, sigma_s: float) -> PFunction:
    """The p-function ``name`` with ``params`` bound, every check done once, here.

    Unknown parameters, the p-function's declared constraints, its ``cross_check`` (e.g.
    ``bounded``'s ``max_gain ≥ 1/σ_S``) and, for a p-function that declares nothing, a dry
    call at ``σ_S/2``.

    Raises:
        ConfigError: Unknown p-function or parameter; ``p_params.<field>`` for a refused value.
    """
    given = dict(params or {})
    try:
        function = registry.load(registry.P_FUNCTIONS, name)
    except Exception as error:  # PluginNotFound / PluginValidationError
        raise ConfigError("p", str(error)) from error
    registry.check_parameters(function, given, "p_params", reserved=("s", "sigma_s"))
    try:
        check_params(function, given)
        cross_check = getattr(function, "cross_check", None)
        if cross_check is not None:
            cross_check(sigma_s, **given)
    except ParameterError as error:
        raise ParameterError(f"p_params.{error.field}", error.message) from None
    bound: PFunction = partial(function, **given) if given else function
    if constraints_of(function) is None:  # undeclared (third party): try it once
        try:
            bound(0.5 * sigma_s, sigma_s)
        except (TypeError, ValueError) as error:
            culprit = registry.blame_parameter(function, given)
            if culprit is None:
                raise ParameterError("p_params", f"invalid for p {name!r}: {error}") from None
            raise ParameterError(f"p_params.{culprit[0]}", culprit[1]) from None
    return bound


#: Builds a NamedTuple from all its fields without the Python-level ``__new__`` (hot path).
_new = tuple.__new__


class OtmmFilter(TaskFilter):
    r"""Suppress the command along the weakest left singular vector(s) of ``J_w``.

    Paper form (``corank: 1``), with :math:`u_s` the left singular vector of σ_min:

    .. math::
        \dot x_m = \dot x - k\,p(\sigma_{min})\,(u_s^\top \dot x)\,u_s,
        \qquad k = \begin{cases}1 & \sigma_{min} \le \sigma_S\\ 0 & \text{otherwise}\end{cases}

    Generalised (``corank: all``): every singular value :math:`\sigma_i \le \sigma_S` is
    filtered along its own :math:`u_i` with its own :math:`p(\sigma_i)`:

    .. math:: \dot x_m = \dot x - \sum_{i:\,\sigma_i \le \sigma_S} p(\sigma_i)(u_i^\top \dot x)u_i

    Since the :math:`u_i` are orthonormal, the two agree whenever at most one σ is below
    σ_S. ``ẋ_m`` never has a larger norm than ``ẋ`` (each component is scaled by ``1−p ∈ [0,1]``).

    Args:
        sigma_s: Threshold σ_S > 0 on the singular value (weighted task units).
        p: Name of a registered p-function (``linear``, ``sqrt``, ``cbrt``, ``power``).
        p_params: Extra parameters of the p-function, e.g. ``{a: 0.5}`` for ``power``.
        corank: ``1`` (paper) or ``"all"`` (every σ_i ≤ σ_S filtered).
    """

    name = "otmm"
    parameter_constraints: ClassVar[Constraints] = {
        "sigma_s": Interval(Real, 0, None, closed="neither"),
        "p": P_NAME,
        "p_params": [P_PARAMS, None],
        "corank": OneOf(1, "all"),
    }

    def __init__(
        self,
        sigma_s: float = DEFAULT_SIGMA_S,
        p: str = "linear",
        p_params: Mapping[str, Any] | None = None,
        corank: int | str = 1,
    ) -> None:
        check_params(self, locals())
        self.sigma_s = float(sigma_s)
        self.corank = corank
        self.p_name = p
        self.p_function = p_function(p, p_params, self.sigma_s)

    def p(self, sigma: float) -> float:
        """Suppression level ``k·p(σ)`` in [0, 1]: 0 above σ_S."""
        if sigma > self.sigma_s:
            return 0.0
        value = self.p_function(sigma, self.sigma_s)
        return 0.0 if value < 0.0 else (1.0 if value > 1.0 else float(value))

    def apply(self, state: KinematicState, xdot: FloatArray) -> FilterOutput:
        """Apply eq. (8) to the weighted command ``xdot``, shape ``(n,)``."""
        sigma = state.sigma
        U = state.U
        n = U.shape[0]  # the task dimension (U is (n, k))
        sigma_s = self.sigma_s
        if sigma.size == n:
            sigma_min = float(sigma[n - 1])
            if sigma_min > sigma_s:
                # tuple.__new__: the NamedTuples without their Python-level __new__.
                report = _new(FilterReport, (False, sigma_min, 0.0, 0.0))
                return _new(FilterOutput, (xdot, report))
        else:
            sigma_min = 0.0
            U, sigma = _full_left_basis(state)
        # σ is sorted descending, so the filtered ones are a tail of length k.
        k = 1
        if self.corank != 1:
            values = sigma.tolist()  # Python floats: no NumPy scalar per comparison
            while k < n and values[n - 1 - k] <= sigma_s:
                k += 1
        if k == 1:  # the paper's case, with scalars only
            u_s = U[:, n - 1]
            p = self.p(sigma_min)
            removed_along = p * float(u_s.dot(xdot))  # p (u_sᵀẋ)
            # ẋ − r u_s as ẋ + (−r) u_s (the same rounding), in the one new array returned.
            modified = np.multiply(u_s, -removed_along)
            np.add(xdot, modified, modified)
            report = _new(FilterReport, (True, sigma_min, p, abs(removed_along)))
            return _new(FilterOutput, (modified, report))
        basis = U[:, n - k :]  # (n, k) the u_i filtered
        p_values = np.array([self.p(float(s)) for s in sigma[n - k :]])  # (k,)
        removed_coefficients = p_values * (xdot @ basis)  # p_i (u_iᵀẋ)
        modified = xdot - basis @ removed_coefficients
        # The u_i are orthonormal, so ‖ẋ − ẋ_m‖ = ‖p ⊙ Uᵀẋ‖.
        removed = math.sqrt(float(removed_coefficients @ removed_coefficients))
        return FilterOutput(modified, FilterReport(True, sigma_min, float(p_values.max()), removed))


def _full_left_basis(state: KinematicState) -> tuple[FloatArray, FloatArray]:
    """Left singular vectors (n, n) and singular values (n,), zero-padded when nv < n."""
    n = state.task_dim
    if state.sigma.size == n:
        return state.U, state.sigma
    # Fewer joints than task rows: the missing directions have σ = 0.
    U_full = np.linalg.svd(state.task_jacobian, full_matrices=True)[0]
    return U_full, np.concatenate([state.sigma, np.zeros(n - state.sigma.size)])
