"""One loader for every YAML file: the hardened reader, the strict schema, one error shaper.

``load(model, path)`` = :func:`~otmm_qp.config.yaml_loader.load_yaml` (size, depth,
alias-bomb and duplicate-key limits, UTF-8, YAML 1.2 numbers) + ``model.model_validate`` +
:func:`parse`'s one-line message naming the first offending field and what is allowed.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

from otmm_qp.config.current_schema import CURRENT_SCHEMA
from otmm_qp.config.schema import SuiteConfig
from otmm_qp.config.yaml_loader import load_yaml
from otmm_qp.exceptions import ConfigError, shown
from otmm_qp.migration.versions import VERSION_KEY, check_schema

#: Longest value shown in an error message [characters].
MESSAGE_VALUE_LIMIT = 80

#: Name of the embedded default config (the paper reproduction).
DEFAULT_CONFIG = "paper.yaml"

Model = TypeVar("Model", bound=BaseModel)


def embedded_config_path(name: str = DEFAULT_CONFIG) -> Path:
    """Path of a config shipped in the package (``configs/`` of the repository)."""
    return Path(str(resources.files("otmm_qp_configs").joinpath(name)))


def _field_path(location: tuple[int | str, ...]) -> str:
    return ".".join(str(part) for part in location)


def parse(model: type[Model], data: Any, source: str) -> Model:
    """Validate already-parsed YAML data as ``model``.

    The file's ``version`` and every key that is gone or changed meaning since it are checked
    first (:func:`~otmm_qp.migration.versions.check_schema`: run files may be of schema 1, study
    files of schema 2 or later); ``version`` is not part of the record.

    Raises:
        ConfigError: ``SOURCE: FIELD.PATH: what is wrong[, got VALUE]`` for the first error,
            or one line listing every key of an older schema.
    """
    if not isinstance(data, dict):
        raise ConfigError(source, f"top level must be a mapping, got {type(data).__name__}")
    oldest = 1 if issubclass(model, SuiteConfig) else 2
    check_schema(data, source, first_version=oldest, current=CURRENT_SCHEMA)
    data = {key: value for key, value in data.items() if key != VERSION_KEY}
    try:
        return model.model_validate(data)
    except ValidationError as error:
        first = error.errors()[0]
        path = _field_path(tuple(first["loc"]))
        message = str(first["msg"])[:300]
        if first["type"] == "extra_forbidden":
            message = "unknown key"
        elif first["type"] in ("literal_error", "finite_number", "string_pattern_mismatch"):
            message = f"{message}, got {shown(first.get('input'), MESSAGE_VALUE_LIMIT)}"
        raise ConfigError(f"{source}: {path}" if path else source, message) from None


def load(model: type[Model], path: str | Path, kind: str = "config") -> Model:
    """Read a YAML file with the hardened reader and validate it as ``model``.

    Args:
        model: The record type (e.g. :class:`SuiteConfig`, ``StudyConfig``).
        path: The file.
        kind: What the file is, for the missing-file message (``config``, ``study``).

    Raises:
        ConfigError: Missing file, malformed or refused YAML (with line and column), or
            invalid content (one line naming the field).
    """
    file = Path(path)
    if not file.is_file():
        raise ConfigError(str(file), f"no such {kind} file")
    return parse(model, load_yaml(file), str(file))


def parse_config(data: Any, source: str = "config") -> SuiteConfig:
    """Validate already-parsed YAML data as a run file (see :func:`parse`)."""
    return parse(SuiteConfig, data, source)


def load_config(path: str | Path) -> SuiteConfig:
    """Read and validate a YAML run file (see :func:`load`)."""
    return load(SuiteConfig, path)
