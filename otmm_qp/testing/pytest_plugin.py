"""Pytest plugin: ``pytest --otmm-controller NAME`` runs the conformance suite on ``NAME``.

Options (repeat ``--otmm-controller`` to test several backends in one session):

* ``--otmm-controller NAME``: registered backend to test;
* ``--otmm-params JSON``: its parameters, e.g. ``'{"damping": 0.1}'`` (applies to all);
* ``--otmm-filters JSON``: filters before it, e.g. ``'[{"type": "otmm", "p": "cbrt"}]'``;
* ``--otmm-scenarios NAMES``: comma-separated subset, e.g. ``paper/E1,paper/E3``.

With ``--otmm-controller`` and no test paths on the command line, only the suite runs;
with paths, the suite is collected in addition to them. One test per (controller, scenario,
check) is generated: ``test_conformance[NAME-paper/E1-joint_speed]``. A peer whose library is
missing is *skipped* with its install hint.

Fixtures for hand-written tests: ``otmm_controller`` (the :class:`ControllerSpec` under test)
and ``otmm_scenario`` (a :class:`Scenario`), both parametrized by the options above.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from otmm_qp.runner.run import RunRecord
    from otmm_qp.testing import conformance

SUITE_FILE = Path(__file__).with_name("suite.py")
_KEY = pytest.StashKey[dict[tuple[str, str], Any]]()


def pytest_addoption(parser: pytest.Parser) -> None:
    """Register the ``--otmm-*`` options."""
    group = parser.getgroup("otmm-qp", "otmm-qp controller conformance suite")
    group.addoption(
        "--otmm-controller",
        action="append",
        default=[],
        metavar="NAME",
        help="registered backend to run through the conformance suite (repeatable)",
    )
    group.addoption("--otmm-params", default=None, metavar="JSON", help="backend parameters")
    group.addoption("--otmm-filters", default=None, metavar="JSON", help="filter blocks")
    group.addoption(
        "--otmm-scenarios", default=None, metavar="NAMES", help="comma-separated scenario subset"
    )


def pytest_configure(config: pytest.Config) -> None:
    """Add the suite module to the collected paths when a controller is named."""
    config.stash[_KEY] = {}
    if not config.getoption("--otmm-controller"):
        return
    # Bad --otmm-params JSON, an unknown controller or scenario: a one-line usage error now,
    # not a collection traceback later.
    from otmm_qp.exceptions import OtmmError

    try:
        _controllers(config)
        _scenarios(config)
    except OtmmError as error:
        raise pytest.UsageError(str(error)) from None
    if config.args_source == pytest.Config.ArgsSource.ARGS:
        config.args.append(str(SUITE_FILE))
    else:
        config.args[:] = [str(SUITE_FILE)]


def _controllers(config: pytest.Config) -> list[conformance.ControllerSpec]:
    from otmm_qp.testing import conformance

    return [
        conformance.parse_controller(
            name, config.getoption("--otmm-params"), config.getoption("--otmm-filters")
        )
        for name in config.getoption("--otmm-controller")
    ]


def _scenarios(config: pytest.Config) -> list[conformance.Scenario]:
    from otmm_qp.testing import conformance

    wanted = config.getoption("--otmm-scenarios")
    found = list(conformance.scenarios())
    if not wanted:
        return found
    names = [n.strip() for n in wanted.split(",") if n.strip()]
    if not names:  # ',' or ' ': nothing would run, and an empty session must not pass
        raise pytest.UsageError(
            f"--otmm-scenarios: {wanted!r:.40} selects no scenario; "
            f"give comma-separated names from: {', '.join(s.name for s in found)}"
        )
    unknown = sorted(set(names) - {s.name for s in found})
    if unknown:
        raise pytest.UsageError(
            f"--otmm-scenarios: unknown {', '.join(unknown)}; "
            f"available: {', '.join(s.name for s in found)}"
        )
    return [s for s in found if s.name in names]


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """Parametrize ``otmm_controller`` × ``otmm_scenario`` (× ``otmm_check``)."""
    names = metafunc.fixturenames
    if "otmm_controller" in names:
        controllers = _controllers(metafunc.config)
        metafunc.parametrize("otmm_controller", controllers, ids=[c.label for c in controllers])
    if "otmm_scenario" in names:
        found = _scenarios(metafunc.config)
        metafunc.parametrize("otmm_scenario", found, ids=[s.name for s in found])
    if "otmm_check" in names:
        from otmm_qp.testing.conformance import CHECKS

        metafunc.parametrize("otmm_check", CHECKS)


@pytest.fixture
def otmm_run(
    request: pytest.FixtureRequest,
    otmm_controller: conformance.ControllerSpec,
    otmm_scenario: conformance.Scenario,
) -> RunRecord:
    """The run of the controller under test on the scenario (simulated once per session)."""
    from otmm_qp.exceptions import ConfigError, PeerUnavailable
    from otmm_qp.testing.conformance import run_scenario

    cache = request.config.stash[_KEY]
    key = (otmm_controller.label, otmm_scenario.name)
    if key not in cache:
        try:
            cache[key] = run_scenario(otmm_scenario, otmm_controller)
        except (PeerUnavailable, ConfigError) as error:
            cache[key] = error
    outcome = cache[key]
    if isinstance(outcome, PeerUnavailable):
        pytest.skip(str(outcome))
    if isinstance(outcome, ConfigError):
        pytest.fail(f"cannot build {otmm_controller.label}: {outcome}", pytrace=False)
    return outcome
