r"""The one escaping function for everything a name or value puts into an HTML page.

Names come from configs a user may not have written (experiment, controller, study, robot
names, warnings, file names). Each reaches a page in one of three contexts, and each context
has its own dangerous characters:

- ``"text"``: element content (``<b>NAME</b>``): ``& < >`` and quotes become entities;
- ``"attr"``: a double- or single-quoted attribute value (``href="NAME"``): the same entities,
  quotes included;
- ``"script"``: a JavaScript value inside ``<script>`` (``const META = VALUE;``): the value is
  JSON with ``<``, ``>``, ``&`` written as ``\u003c``, ``\u003e``, ``\u0026`` (so neither
  ``</script>`` nor ``<!--`` can end or re-mode the script block) and U+2028/U+2029 as
  ``\u2028``/``\u2029`` (line terminators in older JavaScript). NaN/inf are not JSON and are
  written as ``null``.

Templates are filled by :func:`fill_template` in ONE pass over the template's own
placeholders, so text inserted for one placeholder (a title holding ``__META__``) is never
replaced again.
"""

from __future__ import annotations

import html
import json
import math
import re
from collections.abc import Mapping
from typing import Any, Literal

Context = Literal["text", "attr", "script"]

_SCRIPT_UNSAFE = {
    "<": "\\u003c",
    ">": "\\u003e",
    "&": "\\u0026",
    "\u2028": "\\u2028",
    "\u2029": "\\u2029",
}
_SCRIPT_PATTERN = re.compile("[<>&\u2028\u2029]")
_PLACEHOLDER = re.compile(r"__([A-Z](?:[A-Z0-9_]*[A-Z0-9])?)__")


def _finite(value: Any) -> Any:
    """``value`` with every non-finite float replaced by None (JSON has no NaN/inf)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Mapping):
        return {str(k): _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def escape(value: Any, context: Context = "text") -> str:
    """``value`` made safe for one HTML context (see the module docstring).

    Args:
        value: For ``"text"``/``"attr"`` any object (its ``str``); for ``"script"`` any
            JSON-serialisable object (dicts, lists, str, numbers, None; other objects become
            their ``str``).
        context: ``"text"``, ``"attr"`` or ``"script"``.

    Returns:
        The escaped text, to be inserted verbatim.

    Raises:
        ValueError: An unknown ``context``.
    """
    if context in ("text", "attr"):
        return html.escape(str(value), quote=True)
    if context == "script":
        text = json.dumps(_finite(value), separators=(",", ":"), default=str, allow_nan=False)
        return _SCRIPT_PATTERN.sub(lambda m: _SCRIPT_UNSAFE[m.group(0)], text)
    raise ValueError(f"escape context must be 'text', 'attr' or 'script', got {context!r}")


def fill_template(template: str, values: Mapping[str, str]) -> str:
    """Replace every ``__NAME__`` of ``template`` by ``values[NAME]`` in one pass.

    Inserted text is never searched for placeholders again. The values must already be
    escaped for their context (:func:`escape`).

    Raises:
        KeyError: The template holds a placeholder ``values`` does not give.
    """
    return _PLACEHOLDER.sub(lambda m: values[m.group(1)], template)
