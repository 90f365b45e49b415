"""Smaller PNGs for the self-contained HTML reports: screen width, a palette, best compression.

The figures are line plots on white drawn with a handful of colours, so a palette of 128
colours (median cut on the anti-aliased edges) and a width of 720 px keep them readable on
the page while cutting their size about five times; the file on disk is left as written (full
size and colour, linked from ``report.md``). A PNG Pillow cannot read is embedded unchanged.
"""

from __future__ import annotations

import io

__all__ = ["compact_png"]


#: Widest figure embedded [px] (wider ones are scaled down, Lanczos) and palette size: the
#: paper run's 67 figures then take ~2.9 MB of base64 instead of 13 MB.
MAX_WIDTH = 720
COLOURS = 128


def compact_png(data: bytes, max_width: int = MAX_WIDTH, colours: int = COLOURS) -> bytes:
    """``data`` at most ``max_width`` px wide with a ``colours`` palette, if that is smaller."""
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(io.BytesIO(data)) as image:
            rgb = image.convert("RGB")
            if rgb.width > max_width:
                height = max(1, round(rgb.height * max_width / rgb.width))
                rgb = rgb.resize((max_width, height), Image.Resampling.LANCZOS)
            palette = rgb.quantize(colors=colours, method=Image.Quantize.MEDIANCUT)
            buffer = io.BytesIO()
            palette.save(buffer, format="PNG", optimize=True)
    except (UnidentifiedImageError, OSError, ValueError):
        return data
    smaller = buffer.getvalue()
    return smaller if len(smaller) < len(data) else data
