"""Every error otmm-qp raises, rooted at :class:`OtmmError`.

Each exception carries the offending data as attributes and renders as one
line that names the field or value and what is allowed, so the CLI can print
``str(error)`` and exit with status 2.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

#: Longest value shown in an error line [characters] (:func:`shown`).
SHOWN_LIMIT = 40


def shown(value: object, limit: int = SHOWN_LIMIT, *, quote: bool = True) -> str:
    """A value for an error line: its ``repr`` (or ``str`` with ``quote=False``), cut to ``limit``.

    A 10,000-character value becomes its first ``limit − 3`` characters and ``...``, so every
    error stays one short line.
    """
    text = repr(value) if quote else str(value)
    text = text.replace("\n", " ").replace("\r", " ")
    return text if len(text) <= limit else text[: limit - 3] + "..."


#: Longest unbroken run of characters an error line keeps (a value, a path) [characters].
WORD_LIMIT = 60


def one_line(message: str) -> str:
    """An error message as the CLI prints it: one line, every long value cut.

    Line breaks become spaces and every run of more than :data:`WORD_LIMIT` characters without
    a space (a 10,000-character ``--episode`` or plugin name) keeps its start and its end
    around ``...`` (so a long file path still ends in its name and ``:``), so whatever produced
    the message, the line stays readable.
    """
    head = (WORD_LIMIT - 3) // 2
    tail = WORD_LIMIT - 3 - head
    words = " ".join(message.split()).split(" ")
    return " ".join(w if len(w) <= WORD_LIMIT else f"{w[:head]}...{w[-tail:]}" for w in words)


#: Longest first line of an error as the CLI prints it, ``otmm-qp: error: `` included
#: [characters]: what, where and the command that fixes it; details follow on their own lines.
FIRST_LINE_LIMIT = 200


class OtmmError(Exception):
    """Root of all otmm-qp errors.

    Attributes:
        details: Lines printed after the error's first line (one per key, say); empty for
            most errors.
    """

    details: tuple[str, ...] = ()

    @property
    def summary(self) -> str:
        """The first line: what, where and what fixes it (``str(self)`` without details)."""
        return str(self)


def error_lines(error: BaseException, prefix: str = "otmm-qp: error: ") -> list[str]:
    """An error as the CLI prints it: a short first line, then its details, one per line.

    The first line has at most :data:`FIRST_LINE_LIMIT` characters, ``prefix`` included: the
    error's summary made one line (:func:`one_line`); a summary too long for it is broken at a
    space and goes on in indented lines, so nothing is lost.
    """
    summary = error.summary if isinstance(error, OtmmError) else str(error)
    head = prefix + one_line(summary)
    lines: list[str] = []
    while len(head) > FIRST_LINE_LIMIT:
        cut = head.rfind(" ", len(prefix) + 1 if not lines else 5, FIRST_LINE_LIMIT)
        cut = cut if cut > 0 else FIRST_LINE_LIMIT
        lines.append(head[:cut])
        head = "    " + head[cut:].lstrip()
    lines.append(head)
    details = error.details if isinstance(error, OtmmError) else ()
    return lines + [f"  {one_line(line)}" for line in details]


class SchemaChangeWarning(FutureWarning):
    """A keyword given in Python whose meaning changed between schema versions.

    Warned for one release (e.g. ``QpBackend(damping=...)``: μ in 0.1.0, λ since 0.2), with
    the value it would have meant and what to write for it; silence it with
    ``warnings.filterwarnings("ignore", category=SchemaChangeWarning)``.
    """


class ConfigError(OtmmError):
    """A configuration value is malformed, unknown or out of range.

    Attributes:
        field: Dotted path of the offending field, e.g. ``experiments.0.dt``.
        message: What is wrong and what is allowed (one line).
        details: Lines after it, e.g. one per key of an older schema (``str(error)`` has them
            on their own lines).
    """

    def __init__(self, field: str, message: str, details: Sequence[str] = ()) -> None:
        self.field = field
        self.message = message
        self.details = tuple(details)
        self._summary = f"{field}: {message}" if field else message
        super().__init__("\n  ".join((self._summary, *self.details)))

    @property
    def summary(self) -> str:
        """``field: message``, the first line."""
        return self._summary


class ParameterError(ConfigError):
    """A plugin parameter (e.g. ``sigma_s`` of a filter) is out of range."""


class DimensionError(OtmmError):
    """An array has the wrong shape.

    Attributes:
        name: Name of the array.
        expected: Expected shape.
        got: Shape received.
    """

    def __init__(self, name: str, expected: Sequence[int], got: Sequence[int]) -> None:
        self.name = name
        self.expected = tuple(expected)
        self.got = tuple(got)
        super().__init__(f"{name}: expected shape {self.expected}, got {self.got}")


class PluginNotFound(OtmmError):
    """No plugin of that name is registered in an entry-point group.

    Attributes:
        group: Entry-point group, e.g. ``otmm_qp.backends``.
        name: Requested name.
        available: Registered names.
    """

    def __init__(self, group: str, name: str, available: Iterable[str]) -> None:
        self.group = group
        self.name = name
        self.available = sorted(available)
        kind = group.rsplit(".", 1)[-1].replace("_", "-")
        if kind.endswith("ies"):  # trajectories -> trajectory
            kind = kind[:-3] + "y"
        elif kind.endswith("s"):
            kind = kind[:-1]
        super().__init__(
            f"unknown {kind} {name!r}; available: {', '.join(self.available) or '(none)'}"
        )


class PluginValidationError(OtmmError):
    """A registered plugin does not implement its interface, or names clash.

    Attributes:
        plugin: Name of the plugin at fault.
        reason: What is missing or clashing.
    """

    def __init__(self, plugin: str, reason: str) -> None:
        self.plugin = plugin
        self.reason = reason
        super().__init__(f"plugin {plugin!r}: {reason}")


class RobotLoadError(OtmmError):
    """A robot model could not be loaded (unknown name, missing URDF)."""


class FrameNotFound(OtmmError):
    """The requested end-effector frame is not in the model.

    Attributes:
        frame: Requested frame name.
        available: Valid frame names.
    """

    def __init__(self, frame: str, available: Iterable[str]) -> None:
        self.frame = frame
        self.available = sorted(available)
        super().__init__(f"unknown frame {frame!r}; valid frames: {', '.join(self.available)}")


class NotWithinJointLimits(OtmmError):
    """A configuration lies outside the joint position limits.

    Attributes:
        joint: Joint name.
        value: Joint value [rad] or [m].
        lower: Lower limit.
        upper: Upper limit.
    """

    def __init__(self, joint: str, value: float, lower: float, upper: float) -> None:
        self.joint = joint
        self.value = value
        self.lower = lower
        self.upper = upper
        super().__init__(
            f"q0: joint {joint!r} = {value:.6g} is outside its limits [{lower:.6g}, {upper:.6g}]"
        )


class UnreachableTrajectory(ConfigError):
    """The desired trajectory leaves the arm's workspace (raised by the reachability check)."""


class PreviewUnavailable(ConfigError):
    """A controller needs ``x_d(t + τ)`` further ahead than the trajectory can give it.

    Attributes:
        horizon: The preview the controller needs [s].
        lookahead: How far ahead the trajectory is known [s] (0: causal).
    """

    def __init__(self, field: str, trajectory: str, horizon: float, lookahead: float) -> None:
        self.horizon = horizon
        self.lookahead = lookahead
        known = (
            "causal (only x_d(t) is known)" if lookahead <= 0.0 else f"known {lookahead:g} s ahead"
        )
        super().__init__(
            field,
            f"needs the desired path {horizon:g} s ahead, but trajectory {trajectory!r} is "
            f"{known}; shorten the horizon or use the causal counterpart preview_causal",
        )


class OutputPathError(OtmmError):
    """An output path is unusable (outside the results folder, not writable, already used).

    Attributes:
        path: The offending path (as given).
        reason: What is wrong and what is allowed.
    """

    def __init__(self, path: str, reason: str) -> None:
        self.path = path
        self.reason = reason
        shown = path if len(path) <= 120 else path[:117] + "..."
        super().__init__(f"output path {shown!r}: {reason}")


class SolverNotFound(OtmmError):
    """A QP solver name is unknown or not installed.

    Attributes:
        solver: Requested solver.
        available: Installed solvers.
    """

    def __init__(self, solver: str, available: Iterable[str]) -> None:
        self.solver = solver
        self.available = sorted(available)
        super().__init__(
            f"unknown QP solver {solver!r}; installed: {', '.join(self.available)}"
            " (pip install 'qpsolvers[<solver>]' for more)"
        )


class InfeasibleProblem(OtmmError):
    """A QP step has no solution and the infeasibility policy is ``raise``.

    The backend raises it without the step index (a backend does not count steps); the
    simulation loop, which knows the step, states it (``infeasible QP at step k: ...``).

    Attributes:
        step: Index of the control step, or None where unknown (raised by a backend).
        detail: Solver message or which bound conflicts.
        problem: The QP of the step (the evidence), or None.
        solution: The solver's answer (None when the solver was not called).
    """

    def __init__(
        self, step: int | None, detail: str, problem: object = None, solution: object = None
    ) -> None:
        self.step = step
        self.detail = detail
        self.problem = problem
        self.solution = solution
        where = "" if step is None else f" at step {step}"
        super().__init__(f"infeasible QP{where}: {detail}")


class SolverNotConverged(OtmmError):
    """A QP solver stopped before converging (iteration or time limit) and the policy is ``raise``.

    Not :class:`InfeasibleProblem`: the problem may well be feasible (``qp_scaled``'s always is,
    with ``q̇ = 0, α = 0``); the solver did not find its solution. Raised by a backend without
    the step index; the simulation loop states it (``QP solver did not converge at step k``).

    Attributes:
        step: Index of the control step, or None where unknown (raised by a backend).
        detail: The solver's status and what it was solving.
        problem: The QP of the step, or None.
        solution: The solver's answer (its last iterate, when it returns one).
    """

    def __init__(
        self, step: int | None, detail: str, problem: object = None, solution: object = None
    ) -> None:
        self.step = step
        self.detail = detail
        self.problem = problem
        self.solution = solution
        where = "" if step is None else f" at step {step}"
        super().__init__(f"QP solver did not converge{where}: {detail}")


class PeerUnavailable(OtmmError):
    """An optional peer library (pink, mink, drake) is not installed.

    Attributes:
        peer: Peer name.
        hint: Install command.
    """

    def __init__(self, peer: str, hint: str) -> None:
        self.peer = peer
        self.hint = hint
        super().__init__(f"peer {peer!r} is not installed; {hint}")


class PeerModelMismatch(OtmmError):
    """A peer's model of the arm disagrees with ours on the end-effector pose.

    Attributes:
        peer: Peer name.
        position_error: Distance between the two end-effector positions [m].
        orientation_error: Angle between the two end-effector orientations [rad].
    """

    def __init__(self, peer: str, position_error: float, orientation_error: float) -> None:
        self.peer = peer
        self.position_error = position_error
        self.orientation_error = orientation_error
        super().__init__(
            f"peer {peer!r}: its model puts the end effector {position_error:.3g} m and "
            f"{orientation_error:.3g} rad away from Pinocchio's"
        )


class NonFiniteState(OtmmError):
    """A kinematic quantity became NaN or inf (e.g. after a blow-up diverged the arm).

    Attributes:
        quantity: What is non-finite.
    """

    def __init__(self, quantity: str, detail: str) -> None:
        self.quantity = quantity
        super().__init__(f"{quantity}: {detail}")


class SolverFailure(OtmmError):
    """A solver of the offline reference refused or failed a subproblem (OSQP, Clarabel).

    Caught by :func:`~otmm_qp.reference.solve.solve_reference`, which carries it as the
    reference's ``failed`` state (its message in the row's ``reference.message``).
    """


class TimeBudgetExceeded(OtmmError):
    """An offline-reference solve ran past its time budget (its best path so far is kept)."""
