r"""The paper's claims, judged from the metrics of a run of ``configs/paper.yaml``.

Nothing here is written by hand: each verdict is computed from the runs, per loop mode.

Criteria (stated once, applied to every controller alike). For an experiment and loop mode:

* the *nominal speed* ``v_nom`` is the median, over the controllers that move, of the peak
  joint speed ``max ‖q̇‖∞`` **outside** the singular window — what the task
  itself needs;
* a run **breaks** when it blows up (non-finite or above ``blow_up_speed``) or its peak joint
  speed exceeds ``5 v_nom``;
* a run **chatters** when, inside the singular window (``window`` seconds around the minimum of
  σ_min), one step changes a joint speed by more than ``0.5 v_nom`` — half the nominal
  speed within a single control period;
* a claim about the singular window is **not exercised** when σ_min never drops below σ_S
  (no filter acts, every controller is the same pseudoinverse).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from otmm_qp.output.markdown import Table, table_markdown
from otmm_qp.paper import SIGMA_S as DEFAULT_SIGMA_S
from otmm_qp.paths import atomic_write_text
from otmm_qp.runner.run import RunRecord, SuiteResult

BREAK_FACTOR = 5.0
CHATTER_FACTOR = 0.5

HOLDS = "holds"
FAILS = "does not hold"
NOT_EXERCISED = "not exercised"
MISSING = "missing runs"


@dataclass(frozen=True)
class Verdict:
    """One claim in one loop mode."""

    claim: str
    loop_mode: str
    verdict: str
    evidence: str


@dataclass(frozen=True)
class Motion:
    """Speed figures of one run, relative to the singular window.

    Attributes:
        peak: max ‖q̇‖∞ after the first step [rad/s].
        peak_outside: the same outside the singular window [rad/s].
        jump_window: largest one-step ‖Δq̇‖∞ inside the window [rad/s].
        blow_up: the run's blow-up flag.
        exercised: σ_min dropped below σ_S.
    """

    peak: float
    peak_outside: float
    jump_window: float
    blow_up: bool
    exercised: bool


def motion(record: RunRecord, window: float, sigma_s: float) -> Motion:
    """Speed figures of ``record`` (see :class:`Motion`)."""
    r = record.result
    speed = np.max(np.abs(r.qdot), axis=1)
    k_min = int(np.argmin(r.sigma_min))
    inside = np.abs(r.t - r.t[k_min]) <= window / 2.0
    outside = ~inside
    outside[0] = False  # the first step's jump from rest is not the task's speed
    jumps = np.zeros_like(speed)
    jumps[1:] = np.max(np.abs(np.diff(r.qdot, axis=0)), axis=1)
    return Motion(
        peak=float(speed[1:].max()) if speed.size > 1 else 0.0,
        peak_outside=float(speed[outside].max()) if outside.any() else float("nan"),
        jump_window=float(jumps[inside].max()) if inside.any() else 0.0,
        blow_up=bool(record.metrics["blow_up"]),
        exercised=bool(np.any(r.sigma_min < sigma_s)),
    )


class _Judge:
    def __init__(self, result: SuiteResult) -> None:
        self.result = result
        self.window = result.suite.metrics.window
        self.sigma_s = result.suite.metrics.sigma_s

    def records(self, experiment: str, mode: str) -> list[RunRecord]:
        return [
            r
            for r in self.result.records
            if r.result.experiment == experiment and r.result.loop_mode == mode
        ]

    def nominal(self, experiment: str, mode: str) -> float:
        peaks = [
            motion(r, self.window, self.sigma_s).peak_outside
            for r in self.records(experiment, mode)
        ]
        # Median over the controllers that move: robust to one blow-up and to a stuck peer.
        moving = [p for p in peaks if np.isfinite(p) and p > 0.0]
        return float(np.median(moving)) if moving else float("nan")

    def get(self, experiment: str, mode: str, controller: str) -> Motion | None:
        record = self.result.find(experiment, mode, controller)
        return None if record is None else motion(record, self.window, self.sigma_s)

    def describe(self, name: str, m: Motion, v_nom: float) -> str:
        return (
            f"{name}: peak {m.peak:.3g} rad/s ({m.peak / v_nom:.1f}×v_nom), "
            f"window jump {m.jump_window:.3g} rad/s ({m.jump_window / v_nom:.2f}×v_nom)"
            + (", blow-up" if m.blow_up else "")
        )

    @staticmethod
    def breaks(m: Motion, v_nom: float) -> bool:
        return m.blow_up or m.peak > BREAK_FACTOR * v_nom

    @staticmethod
    def chatters(m: Motion, v_nom: float) -> bool:
        return m.jump_window > CHATTER_FACTOR * v_nom


def _misbehaves(
    judge: _Judge, experiment: str, mode: str, names: list[str], expect: bool, claim: str
) -> Verdict:
    """Claim that each of ``names`` breaks or chatters (expect=True) or does neither (False)."""
    v_nom = judge.nominal(experiment, mode)
    motions = {n: judge.get(experiment, mode, n) for n in names}
    if any(m is None for m in motions.values()) or not np.isfinite(v_nom):
        return Verdict(
            claim, mode, MISSING, f"runs {', '.join(names)} of {experiment}/{mode} not found"
        )
    found = {n: m for n, m in motions.items() if m is not None}
    if not all(m.exercised for m in found.values()):
        lowest = min(judge.records(experiment, mode)[0].result.sigma_min)
        return Verdict(
            claim,
            mode,
            NOT_EXERCISED,
            f"σ_min ≥ {lowest:.3g} > σ_S = {judge.sigma_s}: no filter acts",
        )
    bad = {n: judge.breaks(m, v_nom) or judge.chatters(m, v_nom) for n, m in found.items()}
    ok = all(b == expect for b in bad.values())
    evidence = f"v_nom = {v_nom:.3g} rad/s; " + "; ".join(
        judge.describe(n, m, v_nom) for n, m in found.items()
    )
    return Verdict(claim, mode, HOLDS if ok else FAILS, evidence)


def _error_order(judge: _Judge, mode: str, claim: str) -> Verdict:
    names = ["OTMM-linear", "OTMM-sqrt", "OTMM-cbrt"]
    records = [judge.result.find("E1", mode, n) for n in names]
    if any(r is None for r in records):
        return Verdict(claim, mode, MISSING, "OTMM-linear/sqrt/cbrt runs of E1 not found")
    errors = [float(r.metrics["max_error_window"]) for r in records if r is not None]
    active = [bool(np.any(r.result.filter_active)) for r in records if r is not None]
    evidence = ", ".join(f"{n}: {e:.3g} m" for n, e in zip(names, errors, strict=True))
    if not any(active):
        return Verdict(
            claim, mode, NOT_EXERCISED, f"the filters never act; max window error {evidence}"
        )
    ok = errors[0] > errors[1] > errors[2]
    return Verdict(claim, mode, HOLDS if ok else FAILS, "max window error " + evidence)


def _improves(
    judge: _Judge, experiment: str, mode: str, otmm: str, baseline: str, claim: str
) -> Verdict:
    a, b = judge.get(experiment, mode, otmm), judge.get(experiment, mode, baseline)
    if a is None or b is None:
        return Verdict(
            claim, mode, MISSING, f"{otmm} or {baseline} of {experiment}/{mode} not found"
        )
    if not a.exercised:
        return Verdict(claim, mode, NOT_EXERCISED, f"σ_min never below σ_S = {judge.sigma_s}")
    ok = a.peak < b.peak and a.jump_window < b.jump_window and not a.blow_up
    evidence = (
        f"peak {a.peak:.3g} vs {b.peak:.3g} rad/s; "
        f"window jump {a.jump_window:.3g} vs {b.jump_window:.3g} rad/s"
    )
    return Verdict(claim, mode, HOLDS if ok else FAILS, evidence)


def _sigma_s_sweep(judge: _Judge, mode: str, claim: str) -> Verdict:
    """Window error grows with σ_S across the OTMM runs of ``E1_sigma_s``."""
    experiment = next((e for e in judge.result.suite.experiments if e.name == "E1_sigma_s"), None)
    if experiment is None:
        return Verdict(claim, mode, MISSING, "experiment E1_sigma_s not in this config")
    points = []
    for controller in experiment.controllers:
        thresholds = [
            float(f.params.get("sigma_s", DEFAULT_SIGMA_S))
            for f in controller.filters
            if f.type == "otmm"
        ]
        record = judge.result.find(experiment.name, mode, controller.name)
        if record is None or not thresholds:
            continue
        m = motion(record, judge.window, judge.sigma_s)
        points.append(
            (float(thresholds[0]), float(record.metrics["max_error_window"]), m.jump_window)
        )
    if len(points) < 2:
        return Verdict(claim, mode, NOT_EXERCISED, f"E1_sigma_s has no {mode} runs")
    points.sort()
    errors = [e for _, e, _ in points]
    ok = all(a < b for a, b in zip(errors, errors[1:], strict=False))
    evidence = "σ_S → max window error, window jump: " + "; ".join(
        f"{s:g} → {e:.3g} m, {j:.3g} rad/s" for s, e, j in points
    )
    return Verdict(claim, mode, HOLDS if ok else FAILS, evidence)


ClaimFunction = Callable[[_Judge, str, str], Verdict]


def _expect(experiment: str, names: list[str], misbehave: bool) -> ClaimFunction:
    return lambda judge, mode, claim: _misbehaves(judge, experiment, mode, names, misbehave, claim)


#: (claim, how to judge it): the claims of the paper's section 4, plus sensitivity checks.
PAPER_CLAIMS: tuple[tuple[str, ClaimFunction], ...] = (
    ("E1: RMRC chatters or breaks near the singularity (Fig. 2)", _expect("E1", ["RMRC"], True)),
    ("E1: SRI (adaptive DLS) still chatters or breaks (Fig. 3)", _expect("E1", ["SRI"], True)),
    (
        "E1: OTMM with linear, sqrt and cbrt p neither chatters nor breaks (Figs. 4-6)",
        _expect("E1", ["OTMM-linear", "OTMM-sqrt", "OTMM-cbrt"], False),
    ),
    (
        "E1: tracking error in the singular window orders linear > sqrt > cbrt",
        lambda judge, mode, claim: _error_order(judge, mode, claim),
    ),
    (
        "E1: a smaller σ_S lowers the tracking error (section 4, closing remark)",
        lambda judge, mode, claim: _sigma_s_sweep(judge, mode, claim),
    ),
    (
        "E1_nearest: RMRC chatters or breaks when the circle starts 3e-4 rad later",
        _expect("E1_nearest", ["RMRC"], True),
    ),
    (
        "E2: OTMM (cbrt, as in Fig. 7) works from a singular start",
        _expect("E2", ["OTMM-cbrt"], False),
    ),
    ("E2: OTMM with linear p works from a singular start", _expect("E2", ["OTMM-linear"], False)),
    ("E2: RMRC breaks from the singular start", _expect("E2", ["RMRC"], True)),
    (
        "E3: OTMM (cbrt) neither chatters nor breaks on the redundant 4-link arm (Fig. 8)",
        _expect("E3", ["OTMM-cbrt"], False),
    ),
    (
        "E3: OTMM (cbrt) lowers peak speed and window jumps versus the unfiltered pseudoinverse",
        lambda judge, mode, claim: _improves(judge, "E3", mode, "OTMM-cbrt", "RMRC", claim),
    ),
)


def judge_paper_claims(result: SuiteResult) -> list[Verdict]:
    """Every paper claim in every loop mode that was run."""
    judge = _Judge(result)
    modes = sorted(
        {r.result.loop_mode for r in result.records}, key=["feedforward", "clik", "newton"].index
    )
    return [function(judge, mode, claim) for claim, function in PAPER_CLAIMS for mode in modes]


def write_claims(verdicts: list[Verdict], path: Path) -> None:
    """Write ``claims.md``: one row per claim and loop mode, with the evidence numbers."""
    doc = (__doc__ or "").split("Criteria", 1)[1]
    lines = [
        "# The paper's claims, judged from these runs",
        "",
        "Computed by `otmm_qp/output/claims.py` from the metrics of this run; "
        "never written by hand.",
        "",
        "Criteria" + doc.replace(":math:", ""),
    ]
    marks = {HOLDS: "✅ holds", FAILS: "❌ does not hold", NOT_EXERCISED: "➖ not exercised"}
    cells = [[v.claim, v.loop_mode, marks.get(v.verdict, v.verdict), v.evidence] for v in verdicts]
    lines += table_markdown(Table(["claim", "loop mode", "verdict", "evidence"], cells))
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, "\n".join(lines) + "\n")
