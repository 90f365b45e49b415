"""Shared fixtures and problem factories."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import settings

from otmm_qp import registry
from otmm_qp.backends.backend import Backend

settings.register_profile("ci", deadline=None, max_examples=60, derandomize=True)
settings.load_profile("ci")


def make_backend(name: str, **params: object) -> Backend:
    """Instantiate a registered backend by name."""
    backend: Backend = registry.load(registry.BACKENDS, name)(**params)
    return backend


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261123)
