"""The OTMM paper's constants, in one place (every default that reproduces the paper reads them)."""

from __future__ import annotations

#: σ_S: the singular-region threshold of OTMM's suppression level p(σ_min) [task units]; also
#: the metrics' "steps below σ_S" threshold and the replays' shading.
SIGMA_S = 0.05
