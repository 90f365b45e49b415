"""The Python constructors speak as the YAML does: one table of changes for both.

An old keyword raises a ``TypeError`` naming its replacement with the caller's values; the QP
family's ``damping`` (μ in 0.1.0, λ since 0.2) warns a ``SchemaChangeWarning`` (a
``FutureWarning``) with what it meant, for one release, except when built from a config file.
"""

from __future__ import annotations

import ast
import math
import re
import warnings

import pytest

from otmm_qp import registry
from otmm_qp.exceptions import ParameterError, PeerUnavailable, SchemaChangeWarning
from otmm_qp.migration.changes import CHANGES
from otmm_qp_controllers.qp.backend import QpBackend
from tests.factories import OLD_KEYWORD_EXAMPLES

EXAMPLES = OLD_KEYWORD_EXAMPLES  # a value for each old keyword of the table
GONE = [
    (change.key, kind)
    for change in CHANGES
    if change.kind == "name" and change.key in EXAMPLES
    for kind in change.types
]


@pytest.mark.parametrize(("key", "kind"), GONE, ids=[f"{k}-{t}" for k, t in GONE])
def test_old_keyword_is_a_type_error_naming_what_to_write(key: str, kind: str) -> None:
    """Every name change of the table, for every backend it concerns: a TypeError whose
    replacement, written as it says, is accepted by the same constructor."""
    factory = registry.load(registry.BACKENDS, kind)
    with pytest.raises(TypeError, match=f"old keyword argument '{key}': .* write ") as info:
        factory(**{key: EXAMPLES[key]})
    written = str(info.value).rsplit("; write ", 1)[1]
    call = ast.parse(f"f({written})", mode="eval").body
    assert isinstance(call, ast.Call)
    replacement = {k.arg: ast.literal_eval(k.value) for k in call.keywords}
    assert key not in replacement
    try:
        factory(**replacement)
    except PeerUnavailable:  # the peer is not installed: the keywords were accepted
        pass


def test_qp_limit_gain_names_the_limits_list() -> None:
    with pytest.raises(TypeError) as info:
        QpBackend(limit_gain=0.5)  # type: ignore[call-arg]
    assert str(info.value).endswith("write limits=[{'type': 'position', 'gain': 0.5}]")
    assert str(info.value).startswith("QpBackend() got an old keyword argument 'limit_gain'")


@pytest.mark.parametrize("kind", ["qp", "pink"])
@pytest.mark.parametrize("damping", [1e-4, 0.25])
def test_damping_warns_what_it_meant_and_means_lambda(kind: str, damping: float) -> None:
    """``damping=λ`` builds μ = λ², and warns what 0.1.0 read (μ = damping, λ = √damping)."""
    factory = registry.load(registry.BACKENDS, kind)
    with pytest.warns(SchemaChangeWarning) as record:
        backend = factory(damping=damping)
    (warning,) = record
    message = str(warning.message)
    assert re.search(r"in otmm-qp 0\.1\.0 this meant μ", message)
    assert f"write regularization={damping!r} (or damping: {math.sqrt(damping):.6g}" in message
    assert warning.filename == __file__  # points at the caller
    mu = backend.formulation.mu if kind == "qp" else backend.regularization
    assert math.isclose(mu, damping**2, rel_tol=1e-12)


def test_no_warning_from_a_config_nor_for_regularization() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        built = registry.create(registry.BACKENDS, "qp", {"damping": 0.01}, "backend")
        QpBackend(regularization=1e-4)
    assert math.isclose(built.formulation.mu, 1e-4, rel_tol=1e-12)


def test_bad_damping_is_refused_before_any_warning() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ParameterError, match="damping: must be a finite number > 0"):
            QpBackend(damping=-1.0)
