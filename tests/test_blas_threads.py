"""The CLI runs with one BLAS thread unless the user set a count (see otmm_qp.blas_threads)."""

from __future__ import annotations

import os
import subprocess
import sys

from otmm_qp.blas_threads import THREAD_VARIABLES

PROBE = "import os, otmm_qp.cli; print(' '.join(os.environ[v] for v in {vars!r}))"


def _run(extra: dict[str, str]) -> list[str]:
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARIABLES}  # keeps CORETYPE
    env.update(extra)
    code = PROBE.format(vars=THREAD_VARIABLES)
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    return done.stdout.split("\n")


def test_cli_defaults_every_blas_thread_count_to_one() -> None:
    assert _run({})[0] == "1 1 1"


def test_a_user_thread_count_is_kept() -> None:
    assert _run({"OPENBLAS_NUM_THREADS": "2"})[0] == "2 1 1"


def test_the_cli_sets_the_default_before_numpy_loads() -> None:
    """BLAS reads the variables when it loads: record them at NumPy's first import."""
    code = """
import os, sys
seen = []
class Spy:
    def find_spec(self, name, path=None, target=None):
        if name == "numpy" and not seen:
            seen.append(os.environ.get("OPENBLAS_NUM_THREADS"))
        return None
sys.meta_path.insert(0, Spy())
import otmm_qp.cli
from otmm_qp.commands import run
print(seen)
"""
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARIABLES}
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    assert done.stdout.strip() == "['1']"
