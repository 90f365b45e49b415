"""One ``run_episode``: simulate an episode and measure it (used by ``run`` and ``study``)."""

from __future__ import annotations

from dataclasses import dataclass

from otmm_qp.conditioning.pipeline import Conditioning
from otmm_qp.controller import Controller
from otmm_qp.metrics.metrics import Metrics, MetricSettings, compute_metrics
from otmm_qp.plants.chain import PlantChain
from otmm_qp.simulation.episode import Episode
from otmm_qp.simulation.run_result import RunResult
from otmm_qp.simulation.simulate import simulate


@dataclass
class RunRecord:
    """One finished run: its time series and metrics."""

    result: RunResult
    metrics: Metrics

    @property
    def identity(self) -> dict[str, str]:
        """Experiment, loop mode, controller, filters and backend."""
        r = self.result
        return {
            "experiment": r.experiment,
            "loop_mode": r.loop_mode,
            "controller": r.controller,
            "filters": r.filters,
            "backend": r.backend,
        }


def run_episode(
    episode: Episode,
    controller: Controller,
    settings: MetricSettings,
    stage: tuple[PlantChain, Conditioning] | None = None,
) -> RunRecord:
    """Simulate ``controller`` on ``episode`` and compute its metrics.

    ``stage`` is the run's fresh ``(plant, conditioning)`` (None: the ideal plant, none).

    A failure inside the run (a plugin exception, a malformed ``q̇``, an infeasible QP under
    the ``raise`` policy) is not raised: the record keeps the steps done and
    ``result.error_message`` says why.
    """
    plant, conditioning = stage if stage is not None else (None, None)
    result = simulate(episode, controller, plant=plant, conditioning=conditioning)
    return RunRecord(result, compute_metrics(result, settings))
