"""The backend interface: turn a (filtered) task velocity into joint velocities."""

from __future__ import annotations

import abc
import functools
import inspect
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, ClassVar, Final, NamedTuple

import numpy as np

from otmm_qp.exceptions import ParameterError
from otmm_qp.migration.changes import CHANGES
from otmm_qp.migration.keywords import check_keywords, warn_changed
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.status import Status
from otmm_qp.trajectories.preview import information_class
from otmm_qp.trajectories.trajectory import Trajectory

if TYPE_CHECKING:
    from otmm_qp.plants.declaration import PlantDeclaration

#: Singular values below ``RCOND·σ_max`` count as zero: the one rank cutoff of every backend.
RCOND: Final = 1e-10
_TINY: Final = float(np.finfo(float).tiny)


def damping_weight(
    damping: float | None, regularization: float | None, default: float, positive: bool = False
) -> float:
    r"""The weight ``μ`` of ``½‖q̇‖²`` from ``damping`` (λ, then μ = λ²) or ``regularization`` (μ).

    ``damping`` means the DLS damping factor λ [task units] in every backend, as in
    :math:`J^\top(JJ^\top + \lambda^2 I)^{-1}`; a QP-shaped backend (``qp``, ``pink``,
    ``mink``) may instead be given its weight ``regularization: μ`` [task units² / (rad/s)²]
    directly. At most one of the two. Each value's range (a finite number ≥ 0, or > 0) is the
    caller's declared constraint (:mod:`otmm_qp.validation`), checked in its constructor; this
    function checks what relates the two.

    Args:
        damping: λ [task units], or None.
        regularization: μ, or None.
        default: μ when neither is given.
        positive: Whether μ must be > 0 (a λ so small that λ² underflows to 0 is refused).

    Raises:
        ParameterError: Both given, or μ = λ² = 0 where ``positive``.
    """
    if damping is not None and regularization is not None:
        raise ParameterError(
            "regularization", "give damping (λ) or regularization (μ = λ²), not both"
        )
    if damping is None and regularization is None:
        return default
    mu = float(damping) * float(damping) if damping is not None else float(regularization or 0.0)
    if positive and not mu > 0.0:
        field = "damping" if damping is not None else "regularization"
        value = damping if damping is not None else regularization
        raise ParameterError(field, f"must be a finite number > 0, got {value!r:.40}")
    return mu


def rank_cutoff(sigma: FloatArray, rcond: float = RCOND) -> float:
    r"""Threshold below which a singular value is dropped: :math:`\max(r\,\sigma_{max}, tiny)`.

    Args:
        sigma: Singular values, descending, shape ``(k,)``.
        rcond: Relative threshold ``r`` in ``[0, 1)``.
    """
    return max(rcond * float(sigma[0]), _TINY) if sigma.size else _TINY


class BackendOutput(NamedTuple):
    r"""Result of one backend solve.

    Attributes:
        qdot: Joint velocity [rad/s], shape ``(nv,)``.
        status: A :class:`~otmm_qp.status.Status`.
        damping: Damping factor λ [task units] of the step — the λ of
            :math:`J^\top(JJ^\top + \lambda^2 I)^{-1}`, i.e. the QP weight of
            :math:`\|\dot q\|^2` is λ² — NaN when the backend has none.
        scale: Fraction α ∈ [0, 1] of the command realised (1 unless direction-preserving).
        details: What the step solved, for inspection, or None: e.g. the QP backends'
            :class:`~otmm_qp_controllers.qp.QpStep` (its box, the QP and the solver's answer).
            Arrays in it may be the backend's buffers, overwritten by its next step (copy to
            keep).
    """

    qdot: FloatArray
    status: str = Status.OK
    damping: float = float("nan")
    scale: float = 1.0
    details: object = None


class Backend(abc.ABC):
    r"""Resolve ``J_w q̇ ≈ ẋ_w`` for ``q̇``, shape ``(nv,)``.

    The backend receives the step's :class:`~otmm_qp.state.KinematicState` — use its
    ``task_jacobian`` and SVD (``U``, ``sigma``, ``Vt``), never recompute them — and the
    *weighted* command ``ẋ_w``, shape ``(n,)``. :meth:`bind` is called once per run
    before the first step, with the robot (for its limits) and the time step ``dt`` [s];
    allocate persistent solvers there.
    """

    #: The class's own name (e.g. ``"dls"``), a class constant never assigned on an instance;
    #: the name a backend was registered under is kept beside it (``Controller.backend_name``).
    name: ClassVar[str] = "backend"
    #: Whether every returned ``q̇`` honours the robot's speed limits. When False, the
    #: controller reports a faster step ``saturated`` (:func:`otmm_qp.status.classify`).
    enforces_limits: bool = False
    robot: Robot
    dt: float

    def __init_subclass__(cls, **kwargs: Any) -> None:
        """Give the constructor of a backend the table of changes has rows for its keywords.

        An old keyword raises a ``TypeError`` naming what to write; one whose meaning changed
        warns (:func:`otmm_qp.migration.keywords.check_keywords`). The signature is kept.
        """
        super().__init_subclass__(**kwargs)
        if cls.name in _CHANGED_BACKENDS and not getattr(cls.__init__, "_checks_keywords", False):
            cls.__init__ = _checking_keywords(cls.__init__)  # type: ignore[method-assign]

    @property
    def preview_horizon(self) -> float | None:
        """The preview [s] of the desired path the backend reads each step, or None: causal.

        A causal backend sees only the present command ``ẋ_w``; a preview backend reads
        ``x_d(t + τ)`` for ``τ ≤ H`` (:mod:`otmm_qp.trajectories.preview`).
        """
        return None

    @property
    def information(self) -> str:
        """The information class of the backend: ``causal`` or ``preview H s``."""
        return information_class(self.preview_horizon)

    def bind(self, robot: Robot, dt: float) -> None:
        """Attach the robot and the control period ``dt`` [s]; called once per run."""
        self.robot = robot
        self.dt = dt

    def attach(self, trajectory: Trajectory) -> None:  # noqa: B027 - optional hook
        """Hand over the run's desired motion (after :meth:`bind`; read by preview backends).

        A backend with a :attr:`preview_horizon` checks here, before any step, that the
        trajectory can give it (:func:`~otmm_qp.trajectories.preview.check_preview`).
        """

    def reset(self) -> None:  # noqa: B027 - optional hook
        """Forget warm starts and per-run state (called at the start of each run)."""

    def declare_plant(self, declaration: PlantDeclaration) -> None:  # noqa: B027 - optional hook
        """What the run's plant declares about itself (delay, lags, noise), before :meth:`bind`.

        A backend with limits hands it to them (``otmm_qp.limits``); ignored here.
        """

    @abc.abstractmethod
    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Joint velocity for the weighted task velocity ``xdot`` (n,).

        Args:
            state: Kinematic state of this step (shared SVD).
            xdot: Weighted task velocity ``ẋ_w``, shape ``(n,)``.
            qdot_prev: Joint velocity of the previous step [rad/s], shape ``(nv,)``.
        """

    def unconstrained_output(self, qdot: FloatArray, damping: float = np.nan) -> BackendOutput:
        """``BackendOutput(qdot, ok, damping)``: the output of a backend without limits.

        Whether such a step is ``saturated`` (faster than the robot's speed limits) is decided
        by the controller for every backend with :attr:`enforces_limits` False.
        """
        return BackendOutput(qdot, Status.OK, damping)


def svd_work(robot: Robot) -> FloatArray:
    """Buffers for :func:`truncated_pseudoinverse_apply` and DLS on ``robot``: shape ``(2, k)``.

    ``k = min(n, nv)``, the number of singular values of the robot's task Jacobian; a backend
    allocates them in :meth:`Backend.bind` so its step allocates only the ``q̇`` it returns.
    """
    return np.empty((2, min(robot.task_dim, robot.nv)))


def truncated_pseudoinverse_apply(
    state: KinematicState, xdot: FloatArray, rcond: float = RCOND, work: FloatArray | None = None
) -> FloatArray:
    r"""``J_w^+ ẋ`` from the shared SVD, dropping singular values below :func:`rank_cutoff`.

    .. math:: \dot q = \sum_{i:\,\sigma_i > \epsilon} \frac{u_i^\top \dot x}{\sigma_i} v_i

    An exactly singular ``J`` thus uses only its achievable rows (the paper's case).

    Args:
        state: The step's kinematic state (``U`` (n, k), ``sigma`` (k,), ``Vt`` (k, nv)).
        xdot: ``ẋ_w``, shape ``(n,)``.
        rcond: Relative truncation threshold in ``[0, 1)``.
        work: :func:`svd_work` buffers, shape ``(2, k)`` (row 0 is used); None: a temporary.

    Returns:
        ``q̇`` [rad/s], shape ``(nv,)``, a new array.
    """
    sigma = state.sigma
    k = sigma.size
    if not k:
        return np.zeros(state.Vt.shape[1])
    xdot = np.asarray(xdot, dtype=float)
    cutoff = max(rcond * float(sigma[0]), _TINY)  # rank_cutoff, inlined
    if float(sigma[k - 1]) > cutoff:  # full rank: no masking needed (the common case)
        # ndarray.dot into the buffer: uᵢᵀẋ, then divided by σᵢ in place, then Σ cᵢ vᵢ.
        if work is not None and work.shape[1] == k:
            coefficients = xdot.dot(state.U, work[0])
        else:
            coefficients = xdot.dot(state.U)
        np.divide(coefficients, sigma, coefficients)
        result: FloatArray = coefficients.dot(state.Vt)
        return result
    keep = sigma > cutoff
    coefficients = (xdot @ state.U[:, keep]) / sigma[keep]
    return np.asarray(state.Vt[keep].T @ coefficients, dtype=float)


#: The backend types the table of changes has rows for.
_CHANGED_BACKENDS = frozenset(
    t for change in CHANGES if change.group == "backends" for t in change.types
)


def _checking_keywords(init: Callable[..., None]) -> Callable[..., None]:
    """``init`` checking its keywords against the table of changes first (same signature)."""
    parameters = list(inspect.signature(init).parameters.values())[1:]
    accepted = frozenset(
        p.name for p in parameters if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
    )
    positional = [p.name for p in parameters if p.kind == p.POSITIONAL_OR_KEYWORD]

    @functools.wraps(init)
    def checked(self: Backend, *args: Any, **kwargs: Any) -> None:
        given = {**dict(zip(positional, args, strict=False)), **kwargs}
        kind = type(self)
        changed = check_keywords("backends", kind.name, kind.__name__, accepted, given)
        init(self, *args, **kwargs)
        warn_changed(changed)  # once the values are accepted

    checked._checks_keywords = True  # type: ignore[attr-defined]
    return checked
