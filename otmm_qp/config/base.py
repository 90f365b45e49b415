"""The pieces every config record shares: one strict base, plugin blocks, task weights.

Every record is frozen and strict: an unknown key is an error naming its path, and NaN or ±inf
is refused in every float field (``dt: .inf``, ``clik_gain: .inf``, ``q0: [.nan]``,
``duration: {extra: .inf}``, success bounds).
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import AfterValidator, BaseModel, ConfigDict, Field


class Strict(BaseModel):
    """Frozen record, unknown keys refused, NaN/±inf refused in every float field."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class PluginConfig(BaseModel):
    """``{type: NAME, **params}``: a registered plugin and its parameters.

    The parameters are checked against the plugin's constructor when it is built
    (:func:`otmm_qp.registry.create`).
    """

    model_config = ConfigDict(extra="allow", frozen=True)

    type: str = Field(min_length=1)

    @property
    def params(self) -> dict[str, Any]:
        """Parameters other than ``type``."""
        return dict(self.model_extra or {})


def _positive_weights(value: list[float] | None) -> list[float] | None:
    if value is not None and any(not w > 0.0 for w in value):
        raise ValueError("every task weight must be > 0")
    return value


#: A diagonal task weight ``W``, shape ``(n,)``: finite numbers > 0 (its length is checked
#: against the robot's task when the episode is made).
TaskWeight = Annotated[list[float] | None, AfterValidator(_positive_weights)]
