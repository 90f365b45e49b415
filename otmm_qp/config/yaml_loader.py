"""A hardened YAML reader for configs users did not write.

On top of PyYAML's safe loader it refuses duplicate mapping keys, files over
:data:`MAX_BYTES`, nesting deeper than :data:`MAX_DEPTH`, recursive aliases and alias
expansion beyond :data:`MAX_NODES` nodes (an "alias bomb" fails in milliseconds instead of
taking gigabytes), reads ``1e6`` and ``1.0e6`` as numbers (YAML 1.2; YAML 1.1 wanted
``1.0e+6``), and requires UTF-8 text.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import yaml

from otmm_qp.exceptions import ConfigError, shown

#: Largest config file read [bytes].
MAX_BYTES = 1 << 20
#: Deepest nesting of mappings and sequences.
MAX_DEPTH = 40
#: Most nodes the document may hold once aliases are expanded.
MAX_NODES = 200_000

_FLOAT = re.compile(
    r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
    |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""",
    re.X,
)


class _StrictLoader(yaml.SafeLoader):
    """SafeLoader with YAML-1.2 floats and duplicate keys refused."""

    yaml_implicit_resolvers = {
        key: [r for r in resolvers if r[0] != "tag:yaml.org,2002:float"]
        for key, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
    }

    def construct_mapping(self, node: yaml.Node, deep: bool = False) -> dict[Any, Any]:
        if isinstance(node, yaml.MappingNode):
            seen: set[object] = set()
            for key_node, _ in node.value:
                key = self.construct_object(key_node, deep=True)
                try:
                    duplicate = key in seen
                except TypeError:
                    raise yaml.constructor.ConstructorError(
                        None, None, "a mapping key must be a plain value", key_node.start_mark
                    ) from None
                if duplicate:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"duplicate key {shown(key, 60)}", key_node.start_mark
                    )
                seen.add(key)
        return super().construct_mapping(node, deep=deep)  # type: ignore[arg-type]


_StrictLoader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT, list("-+0123456789."))


def _expanded_size(node: yaml.Node, depth: int, sizes: dict[int, int], open_: set[int]) -> int:
    """Nodes under ``node`` with every alias expanded (memoised per shared node)."""
    key = id(node)
    if key in sizes:
        return sizes[key]
    if depth > MAX_DEPTH:
        raise ValueError(f"nesting deeper than {MAX_DEPTH} levels")
    if key in open_:
        raise ValueError("a recursive alias (an anchor used inside itself)")
    open_.add(key)
    total = 1
    if isinstance(node, yaml.SequenceNode):
        children: list[yaml.Node] = list(node.value)
    elif isinstance(node, yaml.MappingNode):
        children = [part for pair in node.value for part in pair]
    else:
        children = []
    for child in children:
        total += _expanded_size(child, depth + 1, sizes, open_)
        if total > MAX_NODES:
            raise ValueError(f"more than {MAX_NODES} values once aliases are expanded")
    open_.discard(key)
    sizes[key] = total
    return total


def load_yaml(file: Path) -> Any:
    """Parse a YAML config file with the limits above.

    Raises:
        ConfigError: Naming the file, what is wrong and (for syntax) the line and column.
    """
    name = str(file)
    try:
        with file.open("rb") as handle:
            raw = handle.read(MAX_BYTES + 1)
    except OSError as error:
        raise ConfigError(name, f"cannot read: {error.strerror}") from None
    if len(raw) > MAX_BYTES:
        raise ConfigError(name, f"larger than {MAX_BYTES} bytes; a config is a small text file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as error:
        raise ConfigError(
            name, f"not UTF-8 text (byte 0x{raw[error.start]:02x} at offset {error.start})"
        ) from None
    try:
        loader = _StrictLoader(text)
    except yaml.YAMLError as error:  # the reader refuses control characters up front
        reason = str(getattr(error, "reason", "") or "unreadable")[:120]
        raise ConfigError(name, f"malformed YAML: {reason}") from None
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _expanded_size(node, 0, {}, set())
        return loader.construct_document(node)
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = str(
            getattr(error, "problem", None) or getattr(error, "reason", None) or "unreadable"
        )[:200]
        raise ConfigError(name, f"malformed YAML{where}: {problem}") from None
    except ValueError as error:
        raise ConfigError(name, f"refused YAML: {error}") from None
    except RecursionError:
        raise ConfigError(name, f"refused YAML: nesting deeper than {MAX_DEPTH} levels") from None
    finally:
        loader.dispose()
