"""The API example runs and shows what it claims."""

import runpy
from pathlib import Path

EXAMPLES = Path(__file__).parents[2] / "examples"


def test_otmm_before_qp_example() -> None:
    module = runpy.run_path(str(EXAMPLES / "otmm_before_qp.py"))
    results = module["main"]()
    for metrics in results.values():
        assert metrics["position_violations"] == 0 and not metrics["blow_up"]
        assert metrics["min_sigma"] < 1e-3  # the wrist singularity is really crossed
        assert metrics["max_error"] < 1e-3
