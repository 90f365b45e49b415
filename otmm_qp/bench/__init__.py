"""Per-step cost of otmm-qp pipelines against pink, mink, Drake and the floor, side by side.

The floor is the arm's kinematics + Jacobian + one SVD (:mod:`otmm_qp.bench.floor`).
:func:`run_bench` is what ``otmm-qp bench`` and ``benchmarks/bench_step.py`` call.
"""

from otmm_qp.bench.run import run_bench

__all__ = ["run_bench"]
