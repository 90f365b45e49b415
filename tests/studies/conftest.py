"""A small planar study shared by the study tests (3 tasks, pinv and dls + the reference)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from otmm_qp.studies.execute import run_study
from otmm_qp.studies.spec import parse_study, plan_study
from tests.factories import tiny_study

SMALL: dict[str, Any] = tiny_study(
    "small",
    seed=5,
    chunk_size=1,
    generators=[
        {"type": "near_singular", "count": 2, "duration": [1.0, 1.5]},
        {"type": "beyond_reach", "count": 1, "duration": [1.0, 1.5]},
    ],
)


@pytest.fixture(scope="session")
def small_study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The folder of :data:`SMALL` run in-process (treat it as read-only)."""
    out = tmp_path_factory.mktemp("small")
    run_study(plan_study(parse_study(SMALL)), out, "small", workers=1)
    return out
