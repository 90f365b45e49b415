"""Read and validate YAML experiment files, with one-line errors naming the field."""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from otmm_qp.config.schema import SuiteConfig
from otmm_qp.config.yaml_loader import load_yaml
from otmm_qp.exceptions import ConfigError

#: Longest value shown in an error message [characters].
MESSAGE_VALUE_LIMIT = 80

#: Name of the embedded default config (the paper reproduction).
DEFAULT_CONFIG = "paper.yaml"


def embedded_config_path(name: str = DEFAULT_CONFIG) -> Path:
    """Path of a config shipped in the package (``configs/`` of the repository)."""
    return Path(str(resources.files("otmm_qp_configs").joinpath(name)))


def _field_path(location: tuple[int | str, ...]) -> str:
    return ".".join(str(part) for part in location)


def parse_config(data: Any, source: str = "config") -> SuiteConfig:
    """Validate already-parsed YAML data.

    Raises:
        ConfigError: Naming the first offending field path and what is allowed.
    """
    if not isinstance(data, dict):
        raise ConfigError(source, f"top level must be a mapping, got {type(data).__name__}")
    try:
        return SuiteConfig.model_validate(data)
    except ValidationError as error:
        first = error.errors()[0]
        path = _field_path(tuple(first["loc"]))
        message = str(first["msg"])[:300]
        if first["type"] == "extra_forbidden":
            message = "unknown key"
        elif first["type"] in ("literal_error", "finite_number", "string_pattern_mismatch"):
            shown = repr(first.get("input"))
            if len(shown) > MESSAGE_VALUE_LIMIT:
                shown = shown[: MESSAGE_VALUE_LIMIT - 3] + "..."
            message = f"{message}, got {shown}"
        raise ConfigError(f"{source}: {path}" if path else source, message) from None


def load_config(path: str | Path) -> SuiteConfig:
    """Read and validate a YAML experiment file.

    Raises:
        ConfigError: Missing file, malformed YAML (with line and column) or invalid content.
    """
    file = Path(path)
    if not file.is_file():
        raise ConfigError(str(file), "no such config file")
    return parse_config(load_yaml(file), str(file))
