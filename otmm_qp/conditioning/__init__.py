"""Output conditioning: named command stages between the controller and the plant."""

from otmm_qp.conditioning.pipeline import Conditioning, build_conditioning
from otmm_qp.conditioning.stage import CommandStage

__all__ = ["CommandStage", "Conditioning", "build_conditioning"]
