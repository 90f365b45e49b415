"""output.png: figures embedded in the HTML reports are palette-compressed, visually unchanged."""

from __future__ import annotations

import io

import numpy as np
from matplotlib.figure import Figure
from PIL import Image

from otmm_qp.output.png import compact_png


def _plot_png() -> bytes:
    figure = Figure(figsize=(6.4, 4.6), dpi=110)
    ax = figure.add_subplot()
    t = np.linspace(0.0, 10.0, 500)
    for k in range(6):
        ax.plot(t, np.sin(t + k), label=f"c{k}")
    ax.legend()
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", pil_kwargs={"compress_level": 1})
    return buffer.getvalue()


def test_a_plot_shrinks_and_looks_the_same() -> None:
    original = _plot_png()
    small = compact_png(original)
    assert len(small) < 0.5 * len(original)
    with Image.open(io.BytesIO(original)) as a, Image.open(io.BytesIO(small)) as b:
        assert a.size == (704, 506) and b.size == a.size  # narrower than 720 px: not scaled
        x = np.asarray(a.convert("RGB"), dtype=int)
        y = np.asarray(b.convert("RGB"), dtype=int)
    assert np.mean(np.abs(x - y)) < 2.0  # mean channel difference out of 255
    assert np.percentile(np.abs(x - y).max(axis=2), 99) < 40


def test_a_wide_figure_is_scaled_to_the_page() -> None:
    buffer = io.BytesIO()
    Image.new("RGB", (1430, 748), "white").save(buffer, format="PNG")
    with Image.open(io.BytesIO(compact_png(buffer.getvalue()))) as image:
        assert image.size == (720, 377)


def test_not_a_png_is_left_alone() -> None:
    assert compact_png(b"not an image") == b"not an image"
