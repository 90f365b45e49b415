"""YAML configuration: one strict base, shared records, one hardened loader for every file."""

from otmm_qp.config.base import PluginConfig, Strict, TaskWeight
from otmm_qp.config.load import (
    DEFAULT_CONFIG,
    embedded_config_path,
    load,
    load_config,
    parse,
    parse_config,
)
from otmm_qp.config.loop import DEFAULT_LOOP_MODES, LoopSettings
from otmm_qp.config.schema import ControllerConfig, ExperimentConfig, MetricsConfig, SuiteConfig

__all__ = [
    "DEFAULT_CONFIG",
    "DEFAULT_LOOP_MODES",
    "ControllerConfig",
    "ExperimentConfig",
    "LoopSettings",
    "MetricsConfig",
    "PluginConfig",
    "Strict",
    "SuiteConfig",
    "TaskWeight",
    "embedded_config_path",
    "load",
    "load_config",
    "parse",
    "parse_config",
]
