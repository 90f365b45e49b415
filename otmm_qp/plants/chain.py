r"""A plant built from stages, in the stated order, with exactly one body.

.. math::
    \tilde q = m_S \circ \dots \circ m_1 (q),\qquad
    \dot q^{a} = c_S \circ \dots \circ c_1 (\dot q^{cmd}),\qquad
    (q^+, \dot q^{act}) = \text{body}(q, \dot q^{a})

Stages are applied in list order on both paths (command: controller → arm; measurement:
arm → controller). A list without a body gets the ideal Euler body
(:class:`~otmm_qp.plants.ideal.IdealPlant`) at its end; two bodies are refused.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from otmm_qp import registry
from otmm_qp.exceptions import ConfigError
from otmm_qp.plants.declaration import PlantDeclaration, combine
from otmm_qp.plants.ideal import IdealPlant
from otmm_qp.plants.plant import Plant, PlantStep
from otmm_qp.plants.presets import PRESET_KEY, expand_preset
from otmm_qp.robots.robot import FloatArray, Robot

__all__ = ["PlantChain", "build_plant", "plant_label"]


class PlantChain:
    """The stages of one plant; the object the simulation loop drives.

    Args:
        stages: Stages in order; at most one body (the ideal body is added when none is).

    Raises:
        ConfigError: More than one body (naming both); a rate limiter after a lag, or rate
            limits of different joint counts (:mod:`otmm_qp.plants.declaration`).
    """

    def __init__(self, stages: Sequence[Plant] = ()) -> None:
        bodies = [s for s in stages if s.body]
        if len(bodies) > 1:
            raise ConfigError(
                "plant",
                "at most one body (ideal, mujoco) per plant, got "
                + ", ".join(b.name for b in bodies),
            )
        _check_rate_limits(stages)
        self.stages: tuple[Plant, ...] = tuple(stages) if bodies else (*stages, IdealPlant())
        self.body: Plant = bodies[0] if bodies else self.stages[-1]
        self._commands = tuple(s for s in self.stages if not s.body)
        self._sensors = tuple(s for s in self.stages if not s.exact_measurement)
        #: Whether the controller sees the true configuration (no measurement stage).
        self.exact_measurement = not self._sensors
        #: Whether the plant is the ideal one (command integrated as is, state seen exactly).
        self.ideal = (
            isinstance(self.body, IdealPlant)
            and not any(type(s).command is not Plant.command for s in self._commands)
            and self.exact_measurement
        )

    def reset(self, robot: Robot, q0: FloatArray, dt: float) -> None:
        """Reset every stage for a run from ``q0`` (nq,) with period ``dt`` [s]."""
        for stage in self.stages:
            stage.reset(robot, q0, dt)

    def measure(self, q: FloatArray) -> FloatArray:
        """What the controller sees (nq,) of the true configuration ``q`` (nq,)."""
        for stage in self._sensors:
            q = stage.measure(q)
        return q

    def advance(self, q: FloatArray, qdot: FloatArray) -> PlantStep:
        """Pass the command (nv,) [rad/s] through the stages and integrate one period."""
        for stage in self._commands:
            qdot = stage.command(qdot)
        return self.body.advance(q, qdot)

    def declares(self, dt: float) -> PlantDeclaration:
        """What the stages declare, combined (:func:`~otmm_qp.plants.declaration.combine`)."""
        return combine(stage.declares(dt) for stage in self.stages)

    def label(self) -> str:
        """``ideal``, or the stage labels joined by ``+`` (``lag(tau=0.02)+delay(steps=1)``)."""
        if self.ideal:
            return "ideal"
        return "+".join(s.label() for s in self.stages if not isinstance(s, IdealPlant))


def _check_rate_limits(stages: Sequence[Plant]) -> None:
    """Refuse what the declared command path cannot model: a rate limiter after a lag.

    Raises:
        ConfigError: Naming the two stages, or the rate limits that do not combine.
    """
    parts = [stage.declares(1.0) for stage in stages]
    # the body acts after every command stage, wherever it is listed
    lag = next((i for i, part in enumerate(parts) if part.lags and not stages[i].body), None)
    for i, part in enumerate(parts):
        if part.acceleration and lag is not None and lag < i:
            raise ConfigError(
                "plant",
                f"stage {i} ({stages[i].name}) limits the command's rate after the lag of stage "
                f"{lag} ({stages[lag].name}); list the rate limiter before every lag",
            )
    try:
        combine(parts)
    except ValueError as error:
        raise ConfigError("plant", str(error)) from None


def _specs(spec: Any) -> list[Mapping[str, Any]]:
    """A plant spec as a list of ``{type, **params}`` mappings (None → ``[]``)."""
    if spec is None:
        return []
    if isinstance(spec, Mapping):
        return [spec]
    if isinstance(spec, Sequence) and not isinstance(spec, str):
        return list(spec)
    raise ConfigError(
        "plant", f"must be a mapping {{type: ...}} or a list of them, got {spec!r:.40}"
    )


def build_plant(spec: Any, field: str = "plant") -> PlantChain:
    """Build a plant from its config: ``{type: lag, tau: 0.02}``, a list of such, or None.

    ``{preset: NAME}`` (alone or as a list entry) stands for the preset's stages
    (:mod:`otmm_qp.plants.presets`).

    Every stage is created through the ``otmm_qp.plants`` entry points (a third-party stage
    registers exactly like the built-ins).

    Raises:
        ConfigError: Unknown stage or parameter, a parameter out of range, two bodies —
            one line naming ``field`` and what is allowed.
    """
    stages: list[Plant] = []
    blocks: list[tuple[str, Any]] = []
    for i, block in enumerate(_specs(spec)):
        where = f"{field}.{i}" if not isinstance(spec, Mapping) else field
        if isinstance(block, Mapping) and PRESET_KEY in block:
            blocks.extend((f"{where}.{PRESET_KEY}", stage) for stage in expand_preset(block, where))
        else:
            blocks.append((where, block))
    for where, block in blocks:
        if not isinstance(block, Mapping) or not isinstance(block.get("type"), str):
            raise ConfigError(
                where, "must be a mapping with a 'type' (a registered plant) or a 'preset'"
            )
        params = {k: v for k, v in block.items() if k != "type"}
        stages.append(registry.create(registry.PLANTS, block["type"], params, where))
    try:
        return PlantChain(stages)
    except ConfigError as error:
        raise ConfigError(field, error.message) from None


def plant_label(spec: Any) -> str:
    """Label of the plant a config describes (``ideal`` for None or ``{type: ideal}``)."""
    return build_plant(spec).label()
