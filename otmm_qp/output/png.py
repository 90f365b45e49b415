"""Smaller PNGs for the self-contained HTML reports: a 256-colour palette, best compression.

The figures are line plots on white drawn with a handful of colours, so a palette of 256
colours (median cut on the anti-aliased edges) keeps them visually unchanged while cutting
their size several times; the file on disk is left as written (full colour, fast to save).
A PNG Pillow cannot read is embedded unchanged.
"""

from __future__ import annotations

import io

__all__ = ["compact_png"]


def compact_png(data: bytes) -> bytes:
    """``data`` re-encoded with a 256-colour palette and zlib level 9, if that is smaller."""
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(io.BytesIO(data)) as image:
            palette = image.convert("RGB").quantize(colors=256, method=Image.Quantize.MEDIANCUT)
            buffer = io.BytesIO()
            palette.save(buffer, format="PNG", optimize=True)
    except (UnidentifiedImageError, OSError, ValueError):
        return data
    smaller = buffer.getvalue()
    return smaller if len(smaller) < len(data) else data
