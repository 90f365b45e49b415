"""Every shipped YAML validates and builds; the registry lists every built-in plugin."""

from pathlib import Path

import pytest

from otmm_qp import registry
from otmm_qp.config import embedded_config_path, load_config
from otmm_qp.runner import prepare_suite

CONFIGS = sorted(
    p
    for p in Path(__file__).parents[2].joinpath("configs").rglob("*.yaml")
    if "studies" not in p.parts  # study files have their own schema (tests/studies/test_shipped.py)
)


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.name)
def test_shipped_config_builds(path: Path) -> None:
    suite = load_config(path)
    prepared = prepare_suite(suite, path.name)
    assert len(prepared) == len(suite.experiments)


def test_embedded_default_is_the_repository_paper_config() -> None:
    shipped = Path(__file__).parents[2] / "configs" / "paper.yaml"
    assert embedded_config_path().read_text() == shipped.read_text()


def test_registry_is_sorted_and_every_entry_loads() -> None:
    for group in registry.GROUPS:
        names = registry.available(group)
        assert names == sorted(names)
        for name in names:
            registry.load(group, name)
    assert {"pinv", "dls", "dls_adaptive", "dls_sigma", "sdls", "qp", "qp_scaled"} <= set(
        registry.available(registry.BACKENDS)
    )
