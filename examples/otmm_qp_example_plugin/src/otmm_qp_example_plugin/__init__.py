"""Example third-party plugin package for otmm-qp (see ``docs/plugins.md``)."""

from otmm_qp_example_plugin.clipped_pinv import ClippedPseudoInverseBackend
from otmm_qp_example_plugin.p_functions import smoothstep

__all__ = ["ClippedPseudoInverseBackend", "smoothstep"]
