"""Shared fixtures and problem factories."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

from otmm_qp import registry
from otmm_qp.backends.backend import Backend

settings.register_profile("ci", deadline=None, max_examples=60, derandomize=True)
settings.load_profile("ci")


#: The slowest test files (paths below ``tests/``), slowest first, with their seconds in the first
#: pass of a clean-clone CI run (2 cores). Under ``--dist loadfile --no-loadscope-reorder`` files
#: go to the workers in collection order; putting these first (longest processing time first)
#: keeps one worker from starting a 100 s file while the other has nothing left. Every other file
#: keeps the random order pytest-randomly gave it; so do the tests within each file.
SLOWEST_FILES = (
    "docs/test_readme_runs.py",  # 119 s: the strategies README commands, run once for the module
    "testing/test_pytest_plugin.py",  # 43 s
    "hostile/test_process.py",  # 33 s
    "controllers/preview/test_backend.py",  # 30 s
    "studies/test_studies.py",  # 28 s
    "docs/test_readme_numbers.py",  # 23 s
    "hostile/test_signals.py",  # 17 s
    "controllers/test_strategies_conformance.py",  # 17 s
)


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Move the tests of :data:`SLOWEST_FILES` to the front, slowest file first (stable)."""
    rank = {name: i for i, name in enumerate(SLOWEST_FILES)}
    here = Path(__file__).parent

    def file_rank(item: pytest.Item) -> int:
        inside = item.path.is_relative_to(here)
        return rank.get(item.path.relative_to(here).as_posix() if inside else "", len(rank))

    items.sort(key=file_rank)


def make_backend(name: str, **params: object) -> Backend:
    """Instantiate a registered backend by name."""
    backend: Backend = registry.load(registry.BACKENDS, name)(**params)
    return backend


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261123)
