"""YAML experiment configuration."""

from otmm_qp.config.load import DEFAULT_CONFIG, embedded_config_path, load_config, parse_config
from otmm_qp.config.schema import (
    ControllerConfig,
    ExperimentConfig,
    MetricsConfig,
    PluginSpec,
    SuiteConfig,
)

__all__ = [
    "DEFAULT_CONFIG",
    "ControllerConfig",
    "ExperimentConfig",
    "MetricsConfig",
    "PluginSpec",
    "SuiteConfig",
    "embedded_config_path",
    "load_config",
    "parse_config",
]
