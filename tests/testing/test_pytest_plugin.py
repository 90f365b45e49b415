"""The conformance pytest plugin, run in a subprocess as a user would run it."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import pytest

from otmm_qp.testing import conformance
from tests.plugin_install import install_example_plugin

PAPER_ONLY = "paper/E1,paper/E2,paper/E3"


def run_pytest(
    tmp_path: Path, *args: str, first_paths: tuple[Path, ...] = ()
) -> subprocess.CompletedProcess[str]:
    """``pytest -p otmm_qp.testing.pytest_plugin ARGS`` in an empty folder.

    ``first_paths`` go first on ``PYTHONPATH`` (e.g. to shadow an installed package).
    """
    paths = [*first_paths, *install_example_plugin(tmp_path / "site")]
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([*map(str, paths), env.get("PYTHONPATH", "")])
    work = tmp_path / "work"
    work.mkdir()
    command = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-q", "-rfs", *args]
    registered = metadata.entry_points(group="pytest11")
    if not any(e.value == "otmm_qp.testing.pytest_plugin" for e in registered):
        command[3:3] = ["-p", "otmm_qp.testing.pytest_plugin"]  # pyproject entry point missing
    return subprocess.run(command, cwd=work, env=env, capture_output=True, text=True, timeout=300)


def counts(output: str) -> dict[str, int]:
    return {kind: int(n) for n, kind in re.findall(r"(\d+) (passed|failed|skipped)", output)}


def test_example_plugin_passes_the_suite(tmp_path: Path) -> None:
    result = run_pytest(tmp_path, "--otmm-controller", "example_clipped_pinv")
    assert result.returncode == 0, result.stdout[-3000:]
    expected = len(conformance.scenarios()) * len(conformance.CHECKS)
    assert counts(result.stdout) == {"passed": expected}


def test_pinv_fails_bounded_speed_at_the_singular_start(tmp_path: Path) -> None:
    result = run_pytest(tmp_path, "--otmm-controller", "pinv", "--otmm-scenarios", PAPER_ONLY)
    assert result.returncode == 1
    assert counts(result.stdout) == {"passed": 10, "failed": 2}
    assert "FAILED" in result.stdout and "paper/E2 joint_speed: max |qdot| = 27" in result.stdout
    assert "paper/E2-tracking" in result.stdout


def test_missing_peer_is_skipped_with_hint(tmp_path: Path) -> None:
    # A meta-path finder (first in line, whatever sys.path order other packages impose)
    # makes `import pink` fail as if pin-pink were not installed.
    (tmp_path / "block").mkdir()
    (tmp_path / "block" / "block_pink.py").write_text(
        "import sys\n"
        "class BlockPink:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'pink' or name.startswith('pink.'):\n"
        "            raise ImportError('pink blocked for the test')\n"
        "sys.meta_path.insert(0, BlockPink())\n"
    )
    result = run_pytest(
        tmp_path,
        "--otmm-controller",
        "pink",
        "--otmm-scenarios",
        "paper/E1",
        "-p",
        "block_pink",
        first_paths=(tmp_path / "block",),
    )
    if "unknown backend 'pink'" in result.stdout:
        pytest.skip("pink entry point not registered yet (pyproject)")
    assert result.returncode == 0, result.stdout[-3000:]
    assert counts(result.stdout) == {"skipped": 4}
    assert "pip install" in result.stdout


def test_unknown_controller_fails_with_the_available_names(tmp_path: Path) -> None:
    result = run_pytest(tmp_path, "--otmm-controller", "nope", "--otmm-scenarios", "paper/E1")
    assert result.returncode == 1
    assert "unknown backend 'nope'; available:" in result.stdout


@pytest.mark.parametrize(
    "backend",
    ["dls", "dls_sigma", "sdls", "qp"],
)
def test_builtin_backends_pass_in_process(backend: str) -> None:
    spec = conformance.ControllerSpec(backend)
    for name, verdicts in conformance.conformance_report(spec).items():
        failed = [v for v in verdicts if not v.passed]
        assert failed == [], (name, failed)


def test_plugin_import_is_light() -> None:
    """Every pytest session in an environment with otmm-qp loads the plugin: keep it cheap."""
    code = (
        "import sys, otmm_qp.testing.pytest_plugin; "
        "print(sorted(m for m in ('scipy', 'pydantic', 'pinocchio', 'otmm_qp.state') "
        "if m in sys.modules))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"
