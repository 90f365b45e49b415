"""Declared parameter constraints (issue 17 point 8): each constraint kind, the declarations of
every built-in plugin against its constructor, the CLI's one-line refusals, ``otmm-qp list``."""

from __future__ import annotations

import inspect
import math
import re
import sys
from numbers import Integral, Real
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from otmm_qp import registry
from otmm_qp.cli import main
from otmm_qp.commands.list import reserved_parameters
from otmm_qp.exceptions import ConfigError, ParameterError
from otmm_qp.validation import (
    ArrayOf,
    Boolean,
    Constraints,
    InstanceOf,
    Interval,
    OneOf,
    check_params,
    constraints_of,
    declaration_problems,
    describe,
    parameters,
    signature_parameters,
)
from tests.cli_errors import refusal_text
from tests.factories import tiny_run

NAN, INF = float("nan"), float("inf")


# --- each constraint kind ------------------------------------------------------------------


@pytest.mark.parametrize(
    ("closed", "at_low", "at_high"),
    [
        ("left", True, False),
        ("right", False, True),
        ("both", True, True),
        ("neither", False, False),
    ],
)
def test_interval_boundaries(closed: Any, at_low: bool, at_high: bool) -> None:
    interval = Interval(Real, 0.0, 1.0, closed=closed)
    assert interval.is_satisfied_by(0.0) is at_low
    assert interval.is_satisfied_by(1.0) is at_high
    assert interval.is_satisfied_by(0.5)
    assert not interval.is_satisfied_by(-1e-300)
    assert not interval.is_satisfied_by(1.0 + 1e-15)
    assert interval.is_satisfied_by(np.float64(0.5)) and interval.is_satisfied_by(np.int64(1)) is (
        at_high
    )


@pytest.mark.parametrize("bad", [NAN, INF, -INF, True, False, "0.5", None, [0.5], np.array(0.5)])
def test_interval_refuses_non_finite_bools_and_other_types(bad: object) -> None:
    for interval in (
        Interval(Real, None, None),
        Interval(Real, 0, None, closed="left"),
        Interval(Real, None, 1, closed="right"),
    ):
        assert not interval.is_satisfied_by(bad), (interval, bad)


def test_interval_integral_and_inf_ok() -> None:
    steps = Interval(Integral, 0, None, closed="left")
    assert steps.is_satisfied_by(0) and steps.is_satisfied_by(3) and steps.is_satisfied_by(2.0)
    assert not steps.is_satisfied_by(2.5) and not steps.is_satisfied_by(-1)
    assert steps.describe() == "an integer >= 0"
    unlimited = Interval(Real, 0, None, closed="neither", inf_ok=True)
    assert unlimited.is_satisfied_by(INF) and not unlimited.is_satisfied_by(-INF)
    assert not unlimited.is_satisfied_by(NAN) and not unlimited.is_satisfied_by(0.0)
    assert unlimited.describe() == "a finite number > 0 (inf: unlimited)"
    with pytest.raises(ValueError, match="bounds must be finite"):
        Interval(Real, 0, INF)
    with pytest.raises(ValueError, match="low 1 > high 0"):
        Interval(Real, 1, 0)
    with pytest.raises(ValueError, match="kind must be"):
        Interval(float, 0, 1)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("constraint", "text"),
    [
        (Interval(Real, 0, None, closed="neither"), "a finite number > 0"),
        (Interval(Real, 0, None, closed="left", unit="rad"), "a finite number >= 0 [rad]"),
        (Interval(Real, None, 5, closed="right"), "a finite number <= 5"),
        (Interval(Real, None, None), "a finite number"),
        (Interval(Real, 0, 1, closed="right"), "in (0, 1]"),
        (Interval(Integral, 1, 9, closed="left"), "an integer in [1, 9)"),
        (OneOf("band", "moveit"), "'band' or 'moveit'"),
        (OneOf("raise", "hold", "dls"), "one of 'raise', 'hold', 'dls'"),
        (Boolean(), "true or false"),
        (
            ArrayOf(Interval(Real, 0, None, closed="neither"), scalar=True, per="joint"),
            "a finite number > 0 or a list of them (one per joint)",
        ),
        (
            ArrayOf(Interval(Real, None, None), length=3),
            "a list of 3 entries, each a finite number",
        ),
    ],
)
def test_describe(constraint: Any, text: str) -> None:
    assert constraint.describe() == text
    assert describe([constraint, None]) == f"{text} or None"


def test_one_of_matches_kind_and_value() -> None:
    corank = OneOf(1, "all")
    assert corank.is_satisfied_by(1) and corank.is_satisfied_by("all")
    assert not corank.is_satisfied_by(True)  # a bool is not the number 1
    assert not corank.is_satisfied_by(2) and not corank.is_satisfied_by("All")
    assert not corank.is_satisfied_by([1]) and not corank.is_satisfied_by(np.array([1, 1]))
    assert OneOf(True).is_satisfied_by(True) and not OneOf(True).is_satisfied_by(1)
    with pytest.raises(ValueError, match="at least one option"):
        OneOf()


def test_boolean() -> None:
    assert Boolean().is_satisfied_by(True) and Boolean().is_satisfied_by(np.bool_(False))
    for bad in (0, 1, "true", None, 1.0):
        assert not Boolean().is_satisfied_by(bad)


def test_array_of_shape_finiteness_and_scalars() -> None:
    positive = Interval(Real, 0, None, closed="neither")
    per_joint = ArrayOf(positive, scalar=True, per="joint")
    assert per_joint.is_satisfied_by(2.0) and per_joint.is_satisfied_by([1, 2.5])
    assert per_joint.is_satisfied_by((1.0,)) and per_joint.is_satisfied_by(np.array([1.0, 3.0]))
    for bad in ([], [[1.0, 2.0]], np.ones((2, 2)), [1.0, NAN], [1.0, INF], [1.0, -1.0], 0.0):
        assert not per_joint.is_satisfied_by(bad), bad
    for bad in ("12", {"a": 1}, [True, 1.0], ["1.0"], None, NAN):
        assert not per_joint.is_satisfied_by(bad), bad
    lists_only = ArrayOf(positive, length=2)
    assert lists_only.is_satisfied_by([1, 2]) and not lists_only.is_satisfied_by([1, 2, 3])
    assert not lists_only.is_satisfied_by(1.0)  # no scalar form


def test_instance_of_and_none() -> None:
    listing = InstanceOf((list, tuple), "a list", exclude=(str,))
    assert listing.is_satisfied_by([]) and not listing.is_satisfied_by("ab")
    assert not listing.is_satisfied_by(None)
    assert describe(None) == "None"


# --- hypothesis: the interval against a direct predicate ----------------------------------

bounds = st.one_of(st.none(), st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False))
values = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-(10**7), 10**7),
    st.booleans(),
    st.text(max_size=3),
    st.none(),
)


@given(bounds, bounds, st.sampled_from(["left", "right", "both", "neither"]), values)
def test_interval_matches_the_predicate(
    low: float | None, high: float | None, closed: Any, value: object
) -> None:
    if low is not None and high is not None and low > high:
        low, high = high, low
    interval = Interval(Real, low, high, closed=closed)
    expected = (
        isinstance(value, int | float)
        and not isinstance(value, bool)
        and math.isfinite(value)
        and (
            low is None or (value >= low if closed in ("left", "both") else value > low)  # type: ignore[operator]
        )
        and (
            high is None or (value <= high if closed in ("right", "both") else value < high)  # type: ignore[operator]
        )
    )
    assert interval.is_satisfied_by(value) is bool(expected)
    if not expected:
        with pytest.raises(ParameterError) as info:
            check_params(_Owner(interval), {"x": value})
        message = str(info.value)
        assert message.startswith(f"x: must be {interval.describe()}, got ")
        assert "\n" not in message and len(message) < 200


entries = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-5, 5),
    st.booleans(),
    st.text(max_size=2),
)


@given(
    st.one_of(
        entries, st.lists(entries, max_size=4), st.lists(st.lists(entries, max_size=2), max_size=2)
    ),
    st.booleans(),
)
def test_array_of_matches_the_predicate(value: object, scalar: bool) -> None:
    """Non-empty flat list of finite numbers ≥ 0 (or one, when ``scalar``), nothing else."""
    element = Interval(Real, 0, None, closed="left")

    def ok(entry: object) -> bool:
        return (
            isinstance(entry, int | float)
            and not isinstance(entry, bool)
            and math.isfinite(entry)
            and entry >= 0
        )

    if isinstance(value, list):
        expected = bool(value) and all(ok(entry) for entry in value)
    else:
        expected = scalar and ok(value)
    assert ArrayOf(element, scalar=scalar).is_satisfied_by(value) is expected


class _Owner:
    """An object declaring one parameter ``x``."""

    def __init__(self, constraint: Any) -> None:
        self.parameter_constraints = {"x": constraint}


def test_check_params_ignores_undeclared_and_accepts_any_option() -> None:
    owner = _Owner([Interval(Real, 0, 1), OneOf("auto"), None])
    check_params(owner, {"x": 0.5, "self": object(), "other": NAN})
    check_params(owner, {"x": "auto"})
    check_params(owner, {"x": None})
    check_params(object(), {"x": NAN})  # nothing declared: nothing checked
    with pytest.raises(ParameterError, match=r"^x: must be in \[0, 1\] or 'auto' or None, got 2"):
        check_params(owner, {"x": 2})
    with pytest.raises(ParameterError, match=r"got 'aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa\.\.\.$"):
        check_params(owner, {"x": "a" * 500})


def test_removed_parameters_are_refused_with_their_replacement() -> None:
    class Renamed:
        removed_parameters: ClassVar[dict[str, str]] = {"old": "renamed to new (the same number)"}

        def __init__(self, new: float = 1.0) -> None:
            self.new = new

    registry.check_parameters(Renamed, {"new": 2.0}, "backend")
    with pytest.raises(ParameterError, match=r"^backend\.old: renamed to new \(the same number\)$"):
        registry.check_parameters(Renamed, {"old": 2.0}, "backend")
    with pytest.raises(ConfigError, match=r"^backend\.olf: unknown parameter; allowed: new$"):
        registry.check_parameters(Renamed, {"olf": 2.0}, "backend")


# --- every built-in plugin ------------------------------------------------------------------

#: Every plugin group: the built-ins of each declare their parameters.
DECLARING_GROUPS = registry.GROUPS
BUILT_INS = [
    (group, name)
    for group in DECLARING_GROUPS
    for name, spec in registry.specs(group).items()
    if spec.distribution == "otmm-qp"
]


def test_every_group_has_built_ins() -> None:
    assert {group for group, _ in BUILT_INS} == set(DECLARING_GROUPS)
    assert len(BUILT_INS) >= 35


@pytest.mark.parametrize(("group", "name"), BUILT_INS)
def test_declarations_are_exactly_the_constructor_parameters(group: str, name: str) -> None:
    """Declared names == constructor parameters, and every default satisfies its declaration."""
    plugin = registry.load(group, name)
    reserved = reserved_parameters(group, plugin)
    assert declaration_problems(plugin, reserved) == []
    declared = constraints_of(plugin)
    assert declared is not None
    accepted = [p.name for p in signature_parameters(plugin, reserved)]
    assert sorted(declared) == sorted(accepted)
    defaults = {
        p.name: p.default
        for p in signature_parameters(plugin, reserved)
        if p.default is not inspect.Parameter.empty
    }
    check_params(plugin, defaults)  # raises if a default were refused
    assert all(row.allowed != "not declared" for row in parameters(plugin, reserved))


def test_declaration_problems_finds_each_kind() -> None:
    class Wrong:
        parameter_constraints: ClassVar[Constraints] = {
            "gain": Interval(Real, 0, None, closed="neither"),
            "gian": Interval(Real, 0, None, closed="neither"),
        }

        def __init__(self, gain: float = 0.0, mode: str = "a") -> None:
            self.gain = gain

    assert declaration_problems(Wrong) == [
        "declared but not a parameter: gian",
        "parameter not declared: mode",
        "default refused: gain: must be a finite number > 0, got 0.0",
    ]
    assert declaration_problems(UndeclaredBackend) == ["no parameter_constraints declared"]


def test_per_step_functions_do_not_validate() -> None:
    """``bounded`` / ``power`` are checked once by the filter: their calls are pure math."""
    from otmm_qp.filters import OtmmFilter
    from otmm_qp.filters import p_functions as pf

    # Values the declarations refuse are not re-checked per call (no raise, just a number).
    assert math.isfinite(pf.bounded(0.01, 0.05, max_gain=1.0))
    with pytest.raises(ParameterError, match=r"^p_params\.max_gain: must be >= 1/sigma_s = 20"):
        OtmmFilter(sigma_s=0.05, p="bounded", p_params={"max_gain": 1.0})
    with pytest.raises(ParameterError, match=r"^p_params\.base: must be one of 'linear'"):
        OtmmFilter(sigma_s=0.05, p="bounded", p_params={"base": "quartic"})


def test_the_gain_cap_check_has_one_home() -> None:
    """``max_gain ≥ 1/σ_S`` is one function, used by ``bounded`` and the directional filter."""
    from otmm_qp.filters.direction_aware_otmm import DirectionAwareOtmmFilter

    sources = {
        path.name: path.read_text()
        for path in (Path(__file__).parents[1] / "otmm_qp" / "filters").glob("*.py")
    }
    assert sum("so p is continuous" in text for text in sources.values()) == 1
    with pytest.raises(ParameterError, match=r"^max_gain: must be >= 1/sigma_s = 20"):
        DirectionAwareOtmmFilter(sigma_s=0.05, max_gain=5.0)


# --- the CLI: one line, exit 2, no traceback, nothing computed ------------------------------

CONFIG = tiny_run(["name: C\nfilters: [FILTER]\nbackend: BACKEND"], duration=0.1)
DEFAULT_FILTER = "{type: identity}"

#: (filter block or None, backend block, pattern of the one error line).
CLI_CASES: dict[str, tuple[str | None, str, str]] = {
    "dls damping nan": (None, "{type: dls, damping: .nan}", r"backend\.damping: must be a finite"),
    "pinv rcond 1": (None, "{type: pinv, rcond: 1.0}", r"backend\.rcond: must be in \[0, 1\), got"),
    "qp policy": (
        None,
        "{type: qp, infeasible_policy: ignore}",
        r"backend\.infeasible_policy: must be one of 'raise', 'hold', 'dls', got 'ignore'",
    ),
    "qp fast_path string": (None, "{type: qp, fast_path: 'yes'}", r"fast_path: must be true or"),
    "qp q_nominal inf": (
        None,
        "{type: qp, posture: {weight: 0.1, q_nominal: [0.0, .inf]}}",
        r"backend\.posture\.q_nominal: must be a list of entries, each a finite number",
    ),
    "qp posture key": (
        None,
        "{type: qp, posture: {wieght: 0.1}}",
        r"backend\.posture\.wieght: unknown parameter; allowed: weight, gain, q_nominal",
    ),
    "qp older posture key": (
        None,
        "{type: qp, posture_weight: 0.1}",
        r"backend\.posture_weight: moved into posture: .*write posture: \{weight: 0\.1\}",
    ),
    "limit gain 2": (
        None,
        "{type: qp, limits: [{type: position, gain: 2}]}",
        r"limits\.0\.gain: must be in \(0, 1\], got 2",
    ),
    "dls_error old name": (
        None,
        "{type: dls_error, damping_floor: 1.0e-4}",
        r"backend\.damping_floor: renamed to lambda_sq_floor, the same number",
    ),
    "jparse gamma bool": (None, "{type: jparse, gamma: true}", r"backend\.gamma: .*got True"),
    "otmm sigma_s -inf": (
        "{type: otmm, sigma_s: -.inf}",
        "{type: pinv}",
        r"filters\.0\.sigma_s: must be a finite number > 0, got -inf",
    ),
    "bounded base": (
        "{type: otmm, p: bounded, p_params: {base: quartic}}",
        "{type: pinv}",
        r"filters\.0\.p_params\.base: must be one of",
    ),
}


@pytest.mark.parametrize("case", sorted(CLI_CASES))
def test_cli_refuses_bad_values_in_one_line(
    case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    filter_block, backend, pattern = CLI_CASES[case]
    config = tmp_path / "bad.yaml"
    config.write_text(
        CONFIG.replace("FILTER", filter_block or DEFAULT_FILTER).replace("BACKEND", backend)
    )
    out = tmp_path / "out"
    status = main(["run", str(config), "--out", str(out), "--quiet"])
    captured = capsys.readouterr()
    assert status == 2, captured.err
    text = refusal_text(captured.err)  # a short first line, details on the lines after
    assert "Traceback" not in captured.out
    assert re.search(pattern, text), text
    assert not any(p.is_file() for p in out.rglob("*")) if out.exists() else True


# --- otmm-qp list ---------------------------------------------------------------------------


def test_list_params_shows_constraints_and_defaults(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["list", "--params", "qp", "otmm", "bounded", "lag"]) == 0
    text = capsys.readouterr().out
    assert "  qp " in text and "  otmm " in text and "  dls " not in text
    assert "robots:" not in text  # only the groups holding the named plugins
    assert "      infeasible_policy = 'raise': one of 'raise', 'hold', 'dls'" in text
    assert "      sigma_s = 0.05: a finite number > 0" in text
    assert "      max_gain = None: a finite number > 0 or None" in text
    assert "      tau = (required): a finite number > 0 [s]" in text
    assert "      limit_gain (refused): removed (limits have one form): write limits: [" in text


def test_list_params_with_an_unknown_name_is_one_line_and_exit_2(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["list", "--params", "qp", "nosuch"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.strip().splitlines() == [
        "otmm-qp: error: --params: no plugin named 'nosuch'; `otmm-qp list` shows the "
        "registered names"
    ]


def test_default_list_is_unchanged_in_shape(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["list"]) == 0
    text = capsys.readouterr().out
    assert "  qp " in text and "otmm_qp_controllers.qp.backend:QpBackend  [otmm-qp]" in text
    assert " = " not in text  # no parameter lines without --params


class UndeclaredBackend:
    """A third-party plugin that declares nothing."""

    def __init__(self, gain: float = 2.0, mode: str = "fast") -> None:
        self.gain = gain


def test_undeclared_plugins_list_their_signature() -> None:
    rows = parameters(UndeclaredBackend)
    assert [(r.name, r.default, r.allowed) for r in rows] == [
        ("gain", "2.0", "not declared"),
        ("mode", "'fast'", "not declared"),
    ]
    check_params(UndeclaredBackend, {"gain": NAN})  # nothing declared: nothing refused


# --- the documented example (docs/plugins.md) -----------------------------------------------


def test_the_plugins_md_example_runs() -> None:
    text = (Path(__file__).parents[1] / "docs" / "plugins.md").read_text()
    block = re.search(r"<!-- declared-example -->\n```python\n(.*?)```", text, re.S)
    assert block is not None, "docs/plugins.md lost its declared-constraints example"
    namespace: dict[str, Any] = {}
    exec(compile(block.group(1), "docs/plugins.md", "exec"), namespace)  # noqa: S102 - our docs
    backend_class = namespace["SpeedCappedBackend"]
    assert declaration_problems(backend_class) == []
    assert backend_class(max_speed=1.0).max_speed == 1.0
    with pytest.raises(ParameterError, match=r"^max_speed: must be a finite number > 0 \[rad/s\]"):
        backend_class(max_speed=float("nan"))
    with pytest.raises(ParameterError, match=r"^mode: must be 'clip' or 'scale', got 'x'$"):
        backend_class(mode="x")
    assert [row.allowed for row in parameters(backend_class)] == [
        "a finite number > 0 [rad/s]",
        "'clip' or 'scale'",
    ]


class _Declares:
    parameter_constraints: ClassVar[Constraints] = {"x": Interval(Real, 0, 1)}

    def __init__(self, x: float = 0.5) -> None:
        check_params(self, locals())


def test_an_instance_checks_at_construction() -> None:
    assert isinstance(_Declares(), _Declares)
    with pytest.raises(ParameterError, match=r"^x: must be in \[0, 1\], got 1\.5$"):
        _Declares(1.5)


def test_the_example_plugin_declares_its_parameters(monkeypatch: pytest.MonkeyPatch) -> None:
    example = Path(__file__).parents[1] / "examples" / "otmm_qp_example_plugin" / "src"
    monkeypatch.syspath_prepend(str(example))
    from otmm_qp_example_plugin.clipped_pinv import ClippedPseudoInverseBackend

    try:
        assert declaration_problems(ClippedPseudoInverseBackend) == []
        with pytest.raises(ParameterError, match=r"^max_speed: must be a finite number > 0"):
            ClippedPseudoInverseBackend(max_speed=-1.0)
    finally:  # leave no import behind for the tests that install the plugin themselves
        for name in [m for m in sys.modules if m.startswith("otmm_qp_example_plugin")]:
            del sys.modules[name]
