"""The report's PNG writer: the pixels it is given, read back by Pillow, and its pixel size."""

from __future__ import annotations

import io

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from PIL import Image

from surrogate.reporting.figures import DPI, png_bytes
from surrogate.reporting.png import png_from_rgba


def _read(png: bytes) -> Image.Image:
    image = Image.open(io.BytesIO(png))
    image.load()
    return image


def test_an_opaque_image_is_written_as_rgb_with_its_pixels_and_dpi():
    pixels = np.random.default_rng(1).integers(0, 256, (7, 5, 4), dtype=np.uint8)
    pixels[..., 3] = 255
    image = _read(png_from_rgba(pixels, 110))
    assert image.mode == "RGB" and image.size == (5, 7)
    np.testing.assert_array_equal(np.asarray(image), pixels[..., :3])
    assert np.allclose(image.info["dpi"], 110, atol=0.01)


def test_an_image_with_transparency_keeps_its_alpha():
    pixels = np.random.default_rng(2).integers(0, 256, (4, 9, 4), dtype=np.uint8)
    image = _read(png_from_rgba(pixels, 72))
    assert image.mode == "RGBA"
    np.testing.assert_array_equal(np.asarray(image), pixels)


def test_a_figure_has_the_pixels_agg_draws():
    figure = Figure(figsize=(3, 2))
    figure.subplots().plot([0, 1, 2], [2, 0, 1], "o-")
    image = _read(png_bytes(figure))
    reference = Figure(figsize=(3, 2), dpi=DPI)
    reference.subplots().plot([0, 1, 2], [2, 0, 1], "o-")
    canvas = FigureCanvasAgg(reference)
    canvas.draw()
    drawn = np.asarray(canvas.buffer_rgba())
    assert image.size == (drawn.shape[1], drawn.shape[0])
    # png_bytes places the title and ticks as the draw would (settled_layout); an untitled
    # panel with default ticks draws alike
    np.testing.assert_array_equal(np.asarray(image), drawn[..., :3])
