r"""The conformance suite: standard scenarios, thresholds and checks for any controller.

A *controller under test* is a registered backend (built-in, peer or third-party) with
optional parameters and filters. It runs, in the ``clik`` loop (gain 10 /s), over:

* the paper scenarios ``paper/E1`` (2-link circle through the stretched singularity),
  ``paper/E2`` (2-link start *at* the singularity) and ``paper/E3`` (redundant 4-link circle
  grazing full stretch), at the paper's dt = 20 ms and full duration;
* each experiment of ``configs/arms/*.yaml`` (when shipped), shortened to
  :data:`ARM_DURATION` seconds, controllers replaced by the one under test.

Checks per scenario (thresholds are module constants, stated here):

1. **finite** — every step finite (no ``nonfinite`` status, no NaN in ``q``/``q̇``) and the
   run completed;
2. **position limits** — no step with a joint outside its position limits (metric
   ``position_violations == 0``);
3. **bounded joint speed near singularities** — :math:`\max_k\|\dot q_k\|_\infty \le`
   :data:`SPEED_BOUND` [rad/s] (the first step, a jump from rest, is excluded as in
   ``max_joint_speed``);
4. **tracking** — ``rms_error`` ≤ :data:`TRACKING_FACTOR` × the best ``rms_error`` of the
   built-in backends on the same scenario + :data:`TRACKING_ATOL` [m]. The reference set is
   every causal backend registered from ``otmm_qp_controllers`` (with
   :data:`REFERENCE_PARAMS`; a preview backend, which reads the path ahead, is left out),
   excluding runs that blew up.

The undamped pseudoinverse (``pinv``, RMRC) fails checks 3 and 4 on ``paper/E2``: that
blow-up is the phenomenon the paper studies, not a defect of the suite.
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from otmm_qp import registry
from otmm_qp.config.load import embedded_config_path, load_config
from otmm_qp.config.schema import SuiteConfig
from otmm_qp.exceptions import ConfigError, OtmmError, PeerUnavailable, PluginValidationError
from otmm_qp.metrics.metrics import MetricSettings
from otmm_qp.runner.prepare import prepare_experiment
from otmm_qp.runner.run import RunRecord, run_experiment

#: Paper experiments in the suite.
PAPER_EXPERIMENTS = ("E1", "E2", "E3")
#: Simulated time of each arm scenario [s].
ARM_DURATION = 1.0
#: Loop mode of every scenario.
LOOP_MODE = "clik"
#: Joint speed bound [rad/s]: 0.4 rad per 20 ms step; built-ins other than pinv peak ≤ 3.6.
SPEED_BOUND = 20.0
#: Allowed ratio to the best built-in RMS tracking error.
TRACKING_FACTOR = 5.0
#: Absolute slack on the tracking check [m] (1 mm: best errors of a few µm make ratios moot).
TRACKING_ATOL = 1e-3
#: Parameters of built-in backends that have no usable defaults.
REFERENCE_PARAMS: dict[str, dict[str, Any]] = {
    "dls_adaptive": {"alpha": 0.003, "sigma_threshold": 0.05},
}
#: Module prefix identifying built-in backends.
BUILTIN_PREFIX = "otmm_qp_controllers."


@dataclass(frozen=True)
class ControllerSpec:
    """A controller under test.

    Attributes:
        backend: Registered backend name.
        params: Backend parameters.
        filters: Filter blocks ``{type: NAME, **params}`` applied before the backend.
    """

    backend: str
    params: Mapping[str, Any] = field(default_factory=dict)
    filters: tuple[Mapping[str, Any], ...] = ()

    @property
    def label(self) -> str:
        """Readable id, e.g. ``dls{"damping": 0.1}``."""
        text = "+".join(str(f["type"]) for f in self.filters)
        text = f"{text}+{self.backend}" if text else self.backend
        return text + (json.dumps(dict(self.params), sort_keys=True) if self.params else "")

    def as_config(self) -> dict[str, Any]:
        """The ``controllers[*]`` block of an experiment YAML."""
        return {
            "name": "candidate",
            "filters": [dict(f) for f in self.filters],
            "backend": {"type": self.backend, **dict(self.params)},
        }


@dataclass(frozen=True)
class Scenario:
    """One standard scenario.

    Attributes:
        name: ``paper/E1``, ``panda_reach/panda_reach_pose``, ...
        suite: The source suite (defaults for dt, gain, metrics).
        experiment: Experiment record as a plain dict (controllers replaced per run).
    """

    name: str
    suite: SuiteConfig
    experiment: Mapping[str, Any]


@dataclass(frozen=True)
class Verdict:
    """Outcome of one check.

    Attributes:
        check: ``finite``, ``position_limits``, ``joint_speed`` or ``tracking``.
        passed: Whether the controller passed.
        detail: Measured value against the threshold, one line.
    """

    check: str
    passed: bool
    detail: str


CHECKS = ("finite", "position_limits", "joint_speed", "tracking")


def arm_configs_dir() -> Path:
    """Directory of the shipped arm configs (may not exist)."""
    return embedded_config_path("arms")


@functools.lru_cache(maxsize=1)
def scenarios() -> tuple[Scenario, ...]:
    """The standard scenarios: paper E1–E3, then every arm experiment found."""
    found: list[Scenario] = []
    paper = load_config(embedded_config_path())
    for experiment in paper.experiments:
        if experiment.name in PAPER_EXPERIMENTS:
            found.append(Scenario(f"paper/{experiment.name}", paper, _plain(experiment)))
    directory = arm_configs_dir()
    if directory.is_dir():
        for path in sorted(directory.glob("*.yaml")):
            suite = load_config(path)
            for experiment in suite.experiments:
                record = _plain(experiment)
                record["duration"] = ARM_DURATION
                found.append(Scenario(f"{path.stem}/{experiment.name}", suite, record))
    return tuple(found)


def _plain(experiment: Any) -> dict[str, Any]:
    return dict(experiment.model_dump(exclude_none=True))


def run_scenario(scenario: Scenario, controller: ControllerSpec) -> RunRecord:
    """Run ``controller`` on ``scenario`` in the ``clik`` loop.

    Raises:
        ConfigError: The controller cannot be built (unknown name, bad parameter).
        PeerUnavailable: The controller is a peer whose library is missing.
    """
    experiment = dict(scenario.experiment)
    experiment["controllers"] = [controller.as_config()]
    experiment["loop_modes"] = [LOOP_MODE]
    data = scenario.suite.model_dump(exclude_none=True)
    data["experiments"] = [experiment]
    data.pop("claims", None)
    suite = SuiteConfig.model_validate(data)
    prepared = prepare_experiment(suite, 0, source=scenario.name)
    for skip in prepared.skipped:
        raise PeerUnavailable(skip.backend, skip.reason)
    settings = MetricSettings(**suite.metrics.model_dump())
    return run_experiment(prepared, settings)[0]


def builtin_backends() -> list[str]:
    """One-step backends registered by ``otmm_qp_controllers`` (the built-in reference set).

    A backend that reads the desired path ahead (``preview_horizon`` set, e.g. ``preview``)
    knows more than the controllers under test and is left out; so is one that plans over a
    horizon of its own (``horizon`` set, e.g. ``preview_causal``): the set is what a
    one-step differential-IK step achieves, the bar a plugin's single step is held to.
    """
    return [
        name
        for name, spec in registry.specs(registry.BACKENDS).items()
        if spec.value.startswith(BUILTIN_PREFIX) and _causal(name)
    ]


def _causal(name: str) -> bool:
    """Whether backend ``name`` (with its reference parameters) is a one-step backend."""
    try:
        backend = registry.create(registry.BACKENDS, name, REFERENCE_PARAMS.get(name, {}), name)
    except OtmmError:  # e.g. a peer library missing: left to run_scenario, which skips it
        return True
    return (
        getattr(backend, "preview_horizon", None) is None
        and getattr(backend, "horizon", None) is None
    )


@functools.cache
def reference_error(scenario_name: str) -> tuple[float, str]:
    """Best RMS error [m] of the built-in backends on a scenario, and which backend.

    Built-ins that cannot be loaded or built here, or that blow up, are left out.

    Raises:
        ConfigError: No built-in backend completed the scenario.
    """
    scenario = next(s for s in scenarios() if s.name == scenario_name)
    best, who = math.inf, ""
    for name in builtin_backends():
        spec = ControllerSpec(name, REFERENCE_PARAMS.get(name, {}))
        try:
            record = run_scenario(scenario, spec)
        except (ConfigError, PluginValidationError, PeerUnavailable):  # e.g. oink not installed
            continue
        metrics = record.metrics
        if metrics["completed"] and not metrics["blow_up"]:
            value = float(metrics["rms_error"])
            if value < best:
                best, who = value, name
    if who == "":
        raise ConfigError(scenario_name, "no built-in backend completed this scenario")
    return best, who


def check(record: RunRecord, scenario: Scenario) -> list[Verdict]:
    """All conformance verdicts of one run (see the module docstring)."""
    metrics = record.metrics
    result = record.result
    finite = bool(
        metrics["status_nonfinite"] == 0
        and np.all(np.isfinite(result.q))
        and np.all(np.isfinite(result.qdot))
    )
    verdicts = [
        Verdict(
            "finite",
            finite and bool(metrics["completed"]),
            f"nonfinite steps {metrics['status_nonfinite']}, completed {metrics['completed']}"
            + (f" ({result.error_message})" if result.error_message else ""),
        ),
        Verdict(
            "position_limits",
            metrics["position_violations"] == 0,
            f"{metrics['position_violations']} steps outside the position limits "
            f"(max excess {float(metrics['max_position_excess']):.3g} rad)",
        ),
        Verdict(
            "joint_speed",
            float(metrics["max_joint_speed"]) <= SPEED_BOUND,
            f"max |qdot| = {float(metrics['max_joint_speed']):.4g} rad/s "
            f"(bound {SPEED_BOUND:g} rad/s)",
        ),
    ]
    best, who = reference_error(scenario.name)
    rms = float(metrics["rms_error"])
    limit = TRACKING_FACTOR * best + TRACKING_ATOL
    verdicts.append(
        Verdict(
            "tracking",
            bool(rms <= limit),
            f"rms error {rms:.3e} m vs limit {limit:.3e} m "
            f"({TRACKING_FACTOR:g} x best built-in {who} {best:.3e} m + {TRACKING_ATOL:g} m)",
        )
    )
    return verdicts


#: Largest ``--otmm-params``/``--otmm-filters`` value [characters] and deepest nesting.
MAX_OPTION_CHARS = 65_536
MAX_OPTION_DEPTH = 40


def _depth(value: Any, limit: int) -> int:
    """Nesting depth of JSON ``value`` (stops counting past ``limit``)."""
    depth, level = 0, [value]
    while level and depth <= limit:
        depth += 1
        level = [
            child
            for item in level
            if isinstance(item, dict | list)
            for child in (item.values() if isinstance(item, dict) else item)
        ]
    return depth


def _json_option(option: str, text: str | None, default: Any) -> Any:
    """Parse one JSON command-line value, bounded in size and nesting.

    Raises:
        ConfigError: Longer than :data:`MAX_OPTION_CHARS`, malformed, or nested deeper than
            :data:`MAX_OPTION_DEPTH` levels.
    """
    if not text:
        return default
    if len(text) > MAX_OPTION_CHARS:
        raise ConfigError(option, f"is longer than {MAX_OPTION_CHARS} characters")
    try:
        value = json.loads(text)
    except RecursionError:
        raise ConfigError(option, f"nesting deeper than {MAX_OPTION_DEPTH} levels") from None
    except json.JSONDecodeError as error:
        raise ConfigError(option, f"invalid JSON: {error}") from None
    if _depth(value, MAX_OPTION_DEPTH) > MAX_OPTION_DEPTH:
        raise ConfigError(option, f"nesting deeper than {MAX_OPTION_DEPTH} levels")
    return value


def parse_controller(
    name: str, params: str | None = None, filters: str | None = None
) -> ControllerSpec:
    """Controller spec from command-line strings.

    Args:
        name: Backend name.
        params: JSON object of backend parameters, e.g. ``'{"damping": 0.1}'``.
        filters: JSON list of filter blocks, e.g. ``'[{"type": "otmm", "p": "cbrt"}]'``.

    Raises:
        ConfigError: Malformed JSON or a wrong type.
    """
    parsed_params = _json_option("--otmm-params", params, {})
    parsed_filters = _json_option("--otmm-filters", filters, [])
    if not isinstance(parsed_params, dict):
        raise ConfigError("--otmm-params", "must be a JSON object")
    if not (isinstance(parsed_filters, list) and all(isinstance(f, dict) for f in parsed_filters)):
        raise ConfigError("--otmm-filters", "must be a JSON list of objects")
    return ControllerSpec(name, parsed_params, tuple(parsed_filters))


def conformance_report(
    controller: ControllerSpec, names: Sequence[str] | None = None
) -> dict[str, list[Verdict]]:
    """Verdicts of ``controller`` on every (or the named) scenario, for scripts.

    Raises:
        ConfigError: The controller cannot be built.
        PeerUnavailable: A peer library is missing.
    """
    out: dict[str, list[Verdict]] = {}
    for scenario in scenarios():
        if names is None or scenario.name in names:
            out[scenario.name] = check(run_scenario(scenario, controller), scenario)
    return out
