r"""The timed pipelines, built through :mod:`otmm_qp.registry` exactly as a YAML config would.

What one *control step* is, per pipeline (everything from the configuration to ``q̇``):

* the floor: the arm's kinematics, Jacobian and one ``dgesdd``, nothing else
  (:mod:`otmm_qp.bench.floor`), the least any pipeline can cost;

* otmm-qp: ``KinematicState.compute(robot, q)`` (kinematics + the one SVD) and
  ``Controller.step(state, ẋ, q̇_prev)`` (filters + backend) — the step of ``otmm-qp run``;
* pink, mink, Drake: the public ``solve(state, ẋ, q̇_prev)`` of the registered adapter
  (:mod:`otmm_qp_controllers.peers`) with its default parameters, as an experiment runs it:
  the peer's own configuration update, task and limits, and its QP (the SVD of ``state`` is unused).
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Collection, Iterator
from dataclasses import dataclass, field
from typing import Any

from otmm_qp import registry
from otmm_qp.bench.floor import FLOOR, floor_step
from otmm_qp.bench.scenarios import DT, Scenario, otmm_controller
from otmm_qp.controller import Controller
from otmm_qp.exceptions import OtmmError
from otmm_qp.state import KinematicState

StepFunction = Callable[[int], None]
#: The pipeline every ratio is taken against.
REFERENCE = "pink (daqp)"
#: Peer libraries (the first word of their pipeline labels).
PEERS = ("pink", "mink", "drake", "oink")
#: QP solvers timed through pink and mink; the otmm-qp ``qp`` solvers compared with each.
PEER_SOLVERS = ("daqp", "proxqp", "osqp")
#: The otmm-qp ``qp`` solvers timed: solver name → (how it runs, the peers' solver it is
#: compared with). ``persistent``: a session set up once, updated in place and warm started;
#: ``qpsolvers``: the stateless qpsolvers call, the problem set up every step.
OUR_SOLVERS: dict[str, tuple[str, str]] = {
    "daqp": ("persistent", "daqp"),
    "proxsuite": ("persistent", "proxqp"),
    "proxqp": ("qpsolvers", "proxqp"),
    "osqp": ("persistent", "osqp"),
}
#: The solver of the pipeline timed with the fast path off (its persistent session).
PERSISTENT_DAQP = "daqp"
EVERY_STEP = "QP every step"
#: The preview pipelines (Panda only): label, backend, parameters — every preview row a study
#: config or the README names (``preview``/``preview-smooth``: the defaults, H = 1 s;
#: ``preview_causal``; ``preview-minmax`` and the deployable ``preview-minmax-k8``) and the
#: horizon and two-rate variants. Each replays the recorded states at their recorded times
#: along the recording run's trajectory; ``hold`` keeps a run-time infeasible QP from stopping
#: the bench (it is timed like any step).
MINMAX = {"horizon": 1.0, "peak": 0.003, "peak_jump": 0.03, "infeasible_policy": "hold"}
#: The deployable preview row (issue 37): 8 knots, working set, the peak weights from the arm's
#: speed limit and the window's task speed (``peak_scale: arm``).
DEPLOYABLE = "preview-k8-arm (deployable)"
#: ``preview-minmax-k8``: the same grid and solve with ``preview-minmax``'s fixed weights.
K8 = {**MINMAX, "knots": 8, "working_set": True, "fast_path": False}
PREVIEWS: tuple[tuple[str, str, dict[str, Any]], ...] = (
    (DEPLOYABLE, "preview", {**K8, "peak": 0.3, "peak_jump": 1.0, "peak_scale": "arm"}),
    ("preview-minmax-k8", "preview", K8),
    ("preview-minmax (16 knots)", "preview", MINMAX),
    ("preview (H = 1 s)", "preview", {"horizon": 1.0, "infeasible_policy": "hold"}),
    ("preview_causal (H = 1 s)", "preview_causal", {"horizon": 1.0, "infeasible_policy": "hold"}),
    ("preview (H = 0.5 s)", "preview", {"horizon": 0.5, "infeasible_policy": "hold"}),
    ("preview (H = 2 s)", "preview", {"horizon": 2.0, "infeasible_policy": "hold"}),
    (
        "preview (H = 2 s, 8 knots)",
        "preview",
        {"horizon": 2.0, "knots": 8, "infeasible_policy": "hold"},
    ),
    (
        "preview two-rate (H = 2 s, preview QP every 10 steps in slices)",
        "preview_two_rate",
        {"horizon": 2.0, "every": 10, "infeasible_policy": "hold"},
    ),
    (
        "preview two-rate (H = 2 s, preview QP every 10 steps, whole)",
        "preview_two_rate",
        {"horizon": 2.0, "every": 10, "infeasible_policy": "hold", "sliced": False},
    ),
)


@dataclass(frozen=True)
class PipelineSpec:
    """One pipeline as a config names it.

    Attributes:
        label: Row label in the tables.
        backend: Registered backend name.
        params: Its YAML parameters.
        otmm: Whether the OTMM filter runs in front (otmm-qp pipelines only).
        peer: Whether the backend is a peer adapter (timed through its ``solve``).
    """

    label: str
    backend: str
    params: dict[str, Any] = field(default_factory=dict)
    otmm: bool = False
    peer: bool = False


def qp_label(solver: str, *notes: str) -> str:
    """``qp (<solver>, <how it runs>[, notes])``, e.g. ``qp (daqp, persistent)``."""
    return f"qp ({', '.join((solver, OUR_SOLVERS[solver][0], *notes))})"


def qp_label_solver(label: str) -> str | None:
    """The solver of a ``qp (<solver>, ...)`` label (``otmm+`` in front allowed), else None."""
    head, _, rest = label.partition(" (")
    if head not in ("qp", "otmm+qp") or not rest:
        return None
    solver = rest.split(",")[0].rstrip(")")
    return solver if solver in OUR_SOLVERS else None


def pipeline_specs(full: bool) -> list[PipelineSpec]:
    """Every pipeline of a scenario: each backend alone and with OTMM, then the peers.

    Args:
        full: Time every QP solver (Panda); otherwise daqp only (planar).
    """
    backends: list[tuple[str, str, dict[str, Any]]] = [
        ("pinv", "pinv", {}),
        ("dls", "dls", {"damping": 0.05}),
        ("dls_adaptive", "dls_adaptive", {"alpha": 0.003, "sigma_threshold": 0.05}),
    ]
    solvers = list(OUR_SOLVERS) if full else [PERSISTENT_DAQP]
    backends += [(qp_label(solver), "qp", {"solver": solver}) for solver in solvers]
    specs: list[PipelineSpec] = []
    for label, backend, params in backends:
        specs.append(PipelineSpec(label, backend, params))
        specs.append(PipelineSpec(f"otmm+{label}", backend, params, otmm=True))
    specs.append(
        PipelineSpec(
            f"otmm+{qp_label(PERSISTENT_DAQP, EVERY_STEP)}", "qp",
            {"solver": PERSISTENT_DAQP, "fast_path": False}, otmm=True,
        )
    )  # fmt: skip
    for peer in ("pink", "mink"):
        for solver in PEER_SOLVERS if full else ("daqp",):
            specs.append(PipelineSpec(f"{peer} ({solver})", peer, {"solver": solver}, peer=True))
    specs.append(PipelineSpec("drake (DiffIK)", "drake", {}, peer=True))
    specs.append(PipelineSpec("oink (ProxQP)", "oink", {}, peer=True))
    if full:
        specs += [PipelineSpec(label, backend, params) for label, backend, params in PREVIEWS]
    return specs


@contextlib.contextmanager
def quiet_logs() -> Iterator[None]:
    """Silence Drake's URDF parser warnings while the peers are built."""
    logger = logging.getLogger("drake")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


def _controller_step(scenario: Scenario, controller: Controller) -> StepFunction:
    robot, qs, xdots, prevs = scenario.robot, scenario.q, scenario.xdot, scenario.qdot_prev
    controller.bind(robot, DT, scenario.trajectory)
    compute, step = KinematicState.compute, controller.step
    seek = getattr(controller.backend, "seek", None)  # a preview backend's clock
    if seek is not None and scenario.times is not None:
        times = scenario.times.tolist()

        def replay(k: int) -> None:
            seek(times[k])
            step(compute(robot, qs[k]), xdots[k], prevs[k])

        return replay

    def run(k: int) -> None:
        step(compute(robot, qs[k]), xdots[k], prevs[k])

    return run


def _adapter_step(scenario: Scenario, spec: PipelineSpec) -> StepFunction:
    adapter = registry.create(registry.BACKENDS, spec.backend, spec.params, spec.label)
    adapter.bind(scenario.robot, DT)
    adapter.reset()
    states = [KinematicState.compute(scenario.robot, q) for q in scenario.q]
    xdots, prevs, solve = scenario.xdot, scenario.qdot_prev, adapter.solve

    def run(k: int) -> None:
        solve(states[k], xdots[k], prevs[k])

    return run


def build_steps(
    scenario: Scenario, full: bool, only: Collection[str] | None = None
) -> tuple[dict[str, StepFunction], list[str]]:
    """Step functions of the floor and of every pipeline that can be built, and notes.

    ``only``: build just the pipelines with these labels (and the floor); None: all.

    The floor (:mod:`otmm_qp.bench.floor`) comes first, with a note saying what it calls. A
    pipeline is left out, with a note, when its peer library is not installed or its
    parameters are not accepted (e.g. a QP solver that is not installed).
    """
    calls, floor = floor_step(scenario)
    steps: dict[str, StepFunction] = {FLOOR: floor}
    notes: list[str] = [f"{FLOOR}: {calls} on the same states, nothing else"]
    for spec in pipeline_specs(full):
        if only is not None and spec.label not in only:
            continue
        try:
            with quiet_logs():
                if spec.peer:
                    steps[spec.label] = _adapter_step(scenario, spec)
                else:
                    controller = (
                        otmm_controller(spec.label, spec.backend, spec.params)
                        if spec.otmm
                        else _plain_controller(spec)
                    )
                    steps[spec.label] = _controller_step(scenario, controller)
        except OtmmError as error:  # missing peer, solver not installed, robot refused
            notes.append(f"{spec.label}: skipped ({error})")
    return steps, notes


def _plain_controller(spec: PipelineSpec) -> Controller:
    backend = registry.create(registry.BACKENDS, spec.backend, spec.params, spec.label)
    return Controller(spec.label, [], backend, backend_name=spec.backend)
