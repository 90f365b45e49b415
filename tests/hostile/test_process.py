"""Hostile input through real processes (issue 9): signals, pipes, C-level stderr, the pytest
plugin's options, and a fuzzer over config mutations."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from otmm_qp.cli import main
from tests.cli_errors import refusal_text
from tests.factories import DLS, PINV, live_processes, tiny_run

ROOT = Path(__file__).resolve().parents[2]
OTMM_QP = [sys.executable, "-m", "otmm_qp.cli"]

LONG = tiny_run(
    [
        PINV,
        DLS,
        "{name: otmm, filters: [{type: otmm, sigma_s: 0.05, p: linear}], backend: {type: pinv}}",
        "{name: dls2, backend: {type: dls, damping: 0.1}}",
    ],
    name="long",
    dt=0.001,
    loop_modes="[clik, feedforward]",
    duration=3.0,
)


def _children(pid: int) -> list[int]:
    """Live processes whose parent is ``pid`` (from /proc)."""
    return live_processes(1, pid)


def _wait_for(predicate: object, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():  # type: ignore[operator]
            return True
        time.sleep(0.02)
    return False


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("phase", ["compute", "figures"])
def test_signal_leaves_reportable_folder_and_no_orphan(
    signum: int, phase: str, tmp_path: Path
) -> None:
    config = tmp_path / "long.yaml"
    # Figures phase: a shorter run, so drawing starts soon; compute phase: a long one.
    config.write_text(LONG if phase == "compute" else LONG.replace("dt: 0.001", "dt: 0.01"))
    out = tmp_path / "out"
    figures = "all" if phase == "figures" else "none"
    process = subprocess.Popen(
        [*OTMM_QP, "run", str(config), "--out", str(out), "--quiet", "--figures", figures],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        cwd=tmp_path,
    )
    if phase == "compute":
        reached = _wait_for(lambda: (out / "summary.csv").is_file(), 60)
    else:
        reached = _wait_for(lambda: bool(_children(process.pid)), 60)
    assert reached, process.stderr.read().decode() if process.poll() is not None else ""
    workers = _children(process.pid)
    process.send_signal(signum)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130, err.decode()
    assert b"Traceback" not in err
    assert _wait_for(lambda: not any(Path(f"/proc/{w}").exists() for w in workers), 10)
    assert not list(out.rglob("*.tmp"))  # no half-written file left
    assert main(["report", str(out)]) == 0  # every finished run is reportable
    rows = (out / "summary.csv").read_text().splitlines()
    assert len(rows) >= 2


def test_list_into_closed_pipe() -> None:
    shell = f"{sys.executable} -m otmm_qp.cli list | head -1"
    done = subprocess.run(shell, shell=True, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0
    assert "Error" not in done.stderr and "Traceback" not in done.stderr, done.stderr
    assert done.stdout.strip().endswith(":")


@pytest.mark.parametrize(
    ("options", "pattern"),
    [
        (["--otmm-params", "{bad json"], "invalid JSON"),
        (["--otmm-params", "[1, 2]"], "must be a JSON object"),
        (["--otmm-scenarios", "nope/X"], "--otmm-scenarios: unknown nope/X"),
        # issue 19: deep nesting is refused, and a selection of nothing never passes vacuously
        (["--otmm-params", '{"a": ' * 5000 + "1" + "}" * 5000], "nesting deeper than 40"),
        (["--otmm-filters", "[" * 100 + "]" * 100], "nesting deeper than 40"),
        (["--otmm-scenarios", ","], "selects no scenario"),
    ],
)
def test_pytest_plugin_bad_options_are_usage_errors(
    options: list[str], pattern: str, tmp_path: Path
) -> None:
    command = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"]
    command += ["--otmm-controller", "pinv", *options]
    done = subprocess.run(command, capture_output=True, text=True, timeout=120, cwd=tmp_path)
    text = done.stdout + done.stderr
    assert done.returncode == 4, text  # pytest's usage-error status
    assert pattern in text
    assert "Traceback" not in text


def test_urdf_load_failure_prints_only_the_error_line(tmp_path: Path) -> None:
    broken = tmp_path / "broken.urdf"
    broken.write_text("<robot name='x'><link name='a'/><joint name='j' type='revolute'>")
    config = tmp_path / "c.yaml"
    config.write_text(
        LONG.replace(
            "{type: planar, link_lengths: [1.0, 0.8]}", f"{{type: pinocchio, urdf: {broken}}}"
        )
    )
    done = subprocess.run(
        [*OTMM_QP, "run", str(config), "--out", str(tmp_path / "o"), "--quiet"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    first, *details = done.stderr.strip().splitlines()
    assert done.returncode == 2, done.stderr
    refusal_text(done.stderr)  # the error line first: urdfdom's lines only as its details
    assert "robot" in first
    assert all(line.startswith(("  urdfdom: ", "    ")) for line in details), done.stderr


GOOD = yaml.safe_load(LONG.replace("duration: 3.0", "duration: 0.1").replace("0.001", "0.02"))

#: Values a hostile config might put anywhere.
NASTY = st.sampled_from(
    [
        None, "", "..", "../../x", "/etc/passwd", "a\x00b", "comparison", "x" * 300,
        -1, 0, 1e308, -1e308, float("inf"), float("nan"), 1e-300, True, [], {}, [1.0], [[1]],
        {"type": "planar"}, "1e6", 2**70,
    ]
)  # fmt: skip
PATHS = st.sampled_from(
    [
        ("name",), ("dt",), ("clik_gain",), ("loop_modes",), ("max_steps",),
        ("experiments", 0, "name"), ("experiments", 0, "q0"), ("experiments", 0, "duration"),
        ("experiments", 0, "dt"), ("experiments", 0, "task_weight"),
        ("experiments", 0, "robot", "link_lengths"), ("experiments", 0, "trajectory", "radius"),
        ("experiments", 0, "trajectory", "type"), ("experiments", 0, "controllers", 0, "name"),
        ("experiments", 0, "controllers", 0, "backend", "damping"),
        ("experiments", 0, "controllers", 1, "backend", "damping"),
        ("experiments", 0, "controllers", 2, "filters", 0, "sigma_s"),
    ]
)  # fmt: skip


def _mutate(data: dict[str, object], path: tuple[object, ...], value: object) -> None:
    target: object = data
    for key in path[:-1]:
        target = target[key]  # type: ignore[index]
    target[path[-1]] = value  # type: ignore[index]


@settings(
    max_examples=25,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(mutations=st.lists(st.tuples(PATHS, NASTY), min_size=1, max_size=3))
def test_fuzzed_configs_never_trace_back_or_escape(
    mutations: list[tuple[tuple[object, ...], object]],
    tmp_path_factory: pytest.TempPathFactory,
    capsys: pytest.CaptureFixture[str],
) -> None:
    import copy

    root = tmp_path_factory.mktemp("fuzz")
    data = copy.deepcopy(GOOD)
    for path, value in mutations:
        _mutate(data, path, value)
    config = root / "c.yaml"
    config.write_text(yaml.safe_dump(data, allow_unicode=True))
    out = root / "out"
    status = main(["run", str(config), "--out", str(out), "--quiet", "--figures", "none"])
    captured = capsys.readouterr()
    assert status in (0, 2), captured.err
    assert "Traceback" not in captured.err
    if status == 2:
        assert captured.err.startswith("otmm-qp: error: ")
        assert len(captured.err) < 2000
    outside = {p.name for p in root.iterdir()} - {"c.yaml", "out"}
    assert not outside, outside
