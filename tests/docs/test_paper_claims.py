"""The paper's claims, asserted from a real run of the embedded paper config.

Claims that hold in our runs are asserted as holding; claims that do not hold are asserted
as not holding, with the numbers, so a change in either direction fails loudly.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from otmm_qp.config import embedded_config_path, load_config
from otmm_qp.output.claims import FAILS, HOLDS, NOT_EXERCISED, judge_paper_claims
from otmm_qp.runner import SuiteResult, run_suite


@pytest.fixture(scope="module")
def paper() -> SuiteResult:
    return run_suite(load_config(embedded_config_path()), None, progress=None)


def metric(paper: SuiteResult, experiment: str, mode: str, controller: str, name: str) -> float:
    record = paper.find(experiment, mode, controller)
    assert record is not None, (experiment, mode, controller)
    return float(record.metrics[name])


def test_e1_clik_rmrc_spikes_at_the_singularity_otmm_does_not(paper: SuiteResult) -> None:
    assert metric(paper, "E1", "clik", "RMRC", "max_joint_speed") > 5.0  # ≈ 10.5 rad/s
    assert metric(paper, "E1", "clik", "RMRC", "min_sigma") < 1e-4  # ≈ 2e-5
    assert metric(paper, "E1", "clik", "RMRC", "t_min_sigma") == pytest.approx(5.0, abs=0.1)
    for p in ["linear", "sqrt", "cbrt"]:
        assert metric(paper, "E1", "clik", f"OTMM-{p}", "max_joint_speed") < 0.8
        assert not metric(paper, "E1", "clik", f"OTMM-{p}", "blow_up")


@pytest.mark.parametrize("mode", ["clik", "newton"])
def test_e1_window_error_orders_linear_sqrt_cbrt(paper: SuiteResult, mode: str) -> None:
    errors = [
        metric(paper, "E1", mode, f"OTMM-{p}", "max_error_window")
        for p in ["linear", "sqrt", "cbrt"]
    ]
    assert errors[0] > errors[1] > errors[2]


def test_e1_feedforward_never_reaches_sigma_s(paper: SuiteResult) -> None:
    """Open loop, the arm drifts inside the circle and σ_min stays above σ_S = 0.05."""
    assert metric(paper, "E1", "feedforward", "RMRC", "min_sigma") > 0.05
    assert metric(paper, "E1", "feedforward", "OTMM-cbrt", "steps_below_sigma_s") == 0


def test_e1_rmrc_spike_is_knife_edge(paper: SuiteResult) -> None:
    """Starting the circle 3e-4 rad later removes the RMRC spike (CLIK)."""
    assert metric(paper, "E1_nearest", "clik", "RMRC", "max_joint_speed") < 1.0


@pytest.mark.parametrize("mode", ["feedforward", "clik", "newton"])
def test_e2_singular_start(paper: SuiteResult, mode: str) -> None:
    """cbrt p spikes (gain (1−p)/σ unbounded), linear p stays smooth, RMRC blows up."""
    assert metric(paper, "E2", mode, "OTMM-cbrt", "max_joint_speed") > 10.0
    assert metric(paper, "E2", mode, "OTMM-linear", "max_joint_speed") < 1.0
    assert metric(paper, "E2", mode, "OTMM-linear", "max_jump") < 0.2
    assert metric(paper, "E2", mode, "RMRC", "blow_up")


def test_e3_otmm_lowers_the_peak_against_pinv(paper: SuiteResult) -> None:
    for mode in ["clik", "newton"]:
        otmm = metric(paper, "E3", mode, "OTMM-cbrt", "max_joint_speed")
        assert otmm < metric(paper, "E3", mode, "RMRC", "max_joint_speed")
        assert otmm < 1.5


def test_claim_verdicts(paper: SuiteResult) -> None:
    verdicts = {
        (v.claim.split(":")[0] + ":" + v.claim.split(":")[1][:25], v.loop_mode): v.verdict
        for v in judge_paper_claims(paper)
    }

    def verdict(prefix: str, mode: str) -> str:
        matches = [
            v for (claim, m), v in verdicts.items() if claim.startswith(prefix) and m == mode
        ]
        assert len(matches) == 1, (prefix, mode)
        return matches[0]

    assert verdict("E1: RMRC chatters", "clik") == HOLDS
    assert verdict("E1: RMRC chatters", "feedforward") == NOT_EXERCISED
    assert verdict("E1: SRI", "clik") == FAILS  # SRI is smooth here, unlike the paper's Fig. 3
    assert verdict("E1: OTMM with linear", "clik") == HOLDS
    assert verdict("E1: tracking error", "clik") == HOLDS
    assert verdict("E2: OTMM (cbrt", "clik") == FAILS  # the Fig. 7 claim does not hold
    assert verdict("E2: OTMM with linear", "clik") == HOLDS
    assert verdict("E2: RMRC breaks", "clik") == HOLDS
    assert verdict("E3: OTMM (cbrt) lowers", "clik") == HOLDS


def test_verdicts_follow_the_metrics(paper: SuiteResult) -> None:
    """Smoothing RMRC's joint speeds flips the RMRC verdict: nothing is hard-coded."""
    doctored = copy.deepcopy(paper)
    rmrc = doctored.find("E1", "clik", "RMRC")
    smooth = doctored.find("E1", "clik", "OTMM-linear")
    assert rmrc is not None and smooth is not None
    rmrc.result.qdot = np.array(smooth.result.qdot)
    rmrc.metrics["blow_up"] = False
    verdict = next(
        v
        for v in judge_paper_claims(doctored)
        if v.claim.startswith("E1: RMRC") and v.loop_mode == "clik"
    )
    assert verdict.verdict == FAILS


def test_a_stuck_controller_does_not_break_the_judge(paper: SuiteResult) -> None:
    """A controller that never moves (e.g. a direction-preserving peer stuck at E2's start)."""
    doctored = copy.deepcopy(paper)
    for record in doctored.records:
        if record.result.experiment == "E2" and record.result.controller == "OTMM-linear":
            record.result.qdot = np.zeros_like(record.result.qdot)
    verdicts = judge_paper_claims(doctored)
    assert all(np.isfinite(len(v.evidence)) for v in verdicts)
    assert any(v.claim.startswith("E2: RMRC") and v.verdict == HOLDS for v in verdicts)


@pytest.mark.parametrize("mode", ["clik", "newton"])
def test_smaller_sigma_s_lowers_error_but_raises_jumps(paper: SuiteResult, mode: str) -> None:
    """The paper's closing remark holds, and the sweep shows its price in one-step jumps."""
    thresholds = ["0.01", "0.02", "0.05", "0.1"]
    errors = [
        metric(paper, "E1_sigma_s", mode, f"OTMM-cbrt-{s}", "max_error_window") for s in thresholds
    ]
    jumps = [metric(paper, "E1_sigma_s", mode, f"OTMM-cbrt-{s}", "max_jump") for s in thresholds]
    assert errors == sorted(errors) and len(set(errors)) == 4
    assert jumps == sorted(jumps, reverse=True)
    verdict = next(
        v
        for v in judge_paper_claims(paper)
        if v.claim.startswith("E1: a smaller σ_S") and v.loop_mode == mode
    )
    assert verdict.verdict == HOLDS
