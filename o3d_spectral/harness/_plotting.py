"""What the harness's plots share: matplotlib on the Agg backend, figures with margins fixed
in inches, panel titles, log axes with decade ticks, and how a figure is written."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

from o3d_spectral.harness._optional import require
from o3d_spectral.harness.constants import DPI, FLOOR, LEGEND_ROOM

__all__ = [
    "DPI",
    "FLOOR",
    "LEGEND_ROOM",
    "draw",
    "figure",
    "log_axis",
    "pyplot",
    "save",
    "title",
    "write_png",
]

#: Room around the panels, inches: left (tick labels and y label), bottom (x label), top
#: (title), between panels.
MARGINS = {"left": 0.75, "bottom": 0.6, "top": 0.4, "wspace": 0.55, "hspace": 0.75}


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend (files only, no window)."""
    matplotlib = require("matplotlib")
    matplotlib.use("Agg")
    return require("matplotlib.pyplot")


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def decade_label(value: float, _position: int | None = None) -> str:
    """A log axis's tick label: ``10⁻³`` at a decade, in plain text (matplotlib's default
    ``$10^{-3}$`` goes through its TeX parser, whose grammar alone took 0.15 s to build)."""
    exponent = np.log10(value) if value > 0 else np.nan
    if np.isfinite(exponent) and abs(exponent - round(exponent)) < 1e-9:
        return "10" + str(int(round(exponent))).translate(_SUPERSCRIPT)
    return f"{value:g}"


def log_axis(ax, which: str = "y") -> None:
    """A log scale with ticks and labels (:func:`decade_label`) at the decades only: the minor
    ticks of a log axis (eight a decade, each with its label and grid line) took most of
    a report's time."""
    ticker = require("matplotlib.ticker")
    (ax.set_yscale if which == "y" else ax.set_xscale)("log")
    axis = ax.yaxis if which == "y" else ax.xaxis
    axis.set_minor_locator(ticker.NullLocator())
    axis.set_major_formatter(ticker.FuncFormatter(decade_label))


def figure(
    plt,
    rows: int,
    columns: int,
    panel: tuple[float, float],
    share: dict[str, bool | str] | None = None,
    **room: float,
):
    """A figure of ``rows x columns`` panels of ``panel`` (width, height) inches, with the
    margins of :data:`MARGINS` (overridden by ``room``, plus ``right``) fixed in inches.

    Fixed margins instead of ``tight_layout`` or ``bbox_inches="tight"``: each of those
    draws the figure once more to measure it, which doubled the time of every plot.
    ``share``: ``sharex`` and ``sharey`` of ``plt.subplots``; a shared axis labels its
    ticks on the outer panels only (fewer texts, the costliest part of drawing a panel).
    """
    margin = MARGINS | {"right": 0.25} | room
    width = margin["left"] + margin["right"] + columns * panel[0]
    width += (columns - 1) * margin["wspace"]
    height = margin["bottom"] + margin["top"] + rows * panel[1] + (rows - 1) * margin["hspace"]
    size = (width, height)
    fig, axes = plt.subplots(rows, columns, figsize=size, dpi=DPI, squeeze=False, **(share or {}))
    fig.subplots_adjust(
        left=margin["left"] / width,
        right=1 - margin["right"] / width,
        bottom=margin["bottom"] / height,
        top=1 - margin["top"] / height,
        wspace=margin["wspace"] / panel[0],
        hspace=margin["hspace"] / panel[1],
    )
    return fig, axes


def title(ax, text: str) -> None:
    """Title a panel at a fixed height: without ``y``, matplotlib measures the panel's
    tick labels at every draw to lift the title over any above the axes (there are none)."""
    ax.set_title(text, fontsize=10, y=1.0)


def _chunk(kind: bytes, data: bytes) -> bytes:
    """A PNG chunk: length, type, data, CRC of type and data."""
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def write_png(fig, path: Path) -> Path:
    """Write the image of ``fig`` as last drawn to ``path``: an 8-bit RGB PNG (the figure is
    opaque) at the figure's resolution, zlib level 3.

    Written here rather than by Pillow, which tries every PNG filter on every row: its
    choice took four times as long as the compression itself. A plot's rows are mostly flat
    colour, which deflate compresses about as well without a filter, so the scanlines are
    written unfiltered (PNG filter type 0).
    """
    buffer = fig.canvas.buffer_rgba()
    height, width = buffer.shape[:2]
    rgba = require("PIL.Image").frombuffer("RGBA", (width, height), buffer, "raw", "RGBA", 0, 1)
    scanlines = np.zeros((height, 1 + 3 * width), np.uint8)  # each: filter type 0, pixels
    # Pillow drops the alpha channel in a third of the time of numpy's strided copy.
    scanlines[:, 1:] = np.asarray(rgba.convert("RGB")).reshape(height, 3 * width)
    per_metre = int(fig.dpi / 0.0254 + 0.5)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n"
        + _chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
        + _chunk(b"pHYs", struct.pack(">IIB", per_metre, per_metre, 1))
        + _chunk(b"IDAT", zlib.compress(scanlines, 3))
        + _chunk(b"IEND", b"")
    )
    return path


def _ticks_in_view(axis) -> None:
    """Fix ``axis``'s ticks to those its locator gives within the view, labelled as its
    formatter labels them among all it gives.

    A locator also gives a tick or more beyond each end of the view, and matplotlib makes a
    tick object (three lines, two labels) for every tick given, drawn or not: a third of
    the ticks of these figures, and making them took more time than drawing the others.
    """
    ticker = require("matplotlib.ticker")
    if isinstance(axis.get_major_locator(), ticker.NullLocator):
        return
    ticks = axis.get_majorticklocs()
    labels = np.array(axis.major.formatter.format_ticks(ticks), dtype=object)
    offset = axis.major.formatter.get_offset()
    scale = axis.get_transform()  # where ticks are on the axis (log10 on a log axis)
    low, high = sorted(scale.transform(axis.get_view_interval()))
    at, margin = scale.transform(ticks), 1e-6 * (high - low)  # wider than matplotlib's
    shown = (at >= low - margin) & (at <= high + margin)
    axis.set_major_locator(ticker.FixedLocator(ticks[shown]))
    formatter = ticker.FixedFormatter(list(labels[shown]))
    formatter.set_offset_string(offset)
    axis.set_major_formatter(formatter)


def draw(fig) -> None:
    """Draw ``fig`` with only the ticks in view made (:func:`_ticks_in_view`); its limits
    must be final."""
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            _ticks_in_view(axis)
    fig.canvas.draw()


def save(fig, plt, path: Path) -> Path:
    """Draw ``fig`` (:func:`draw`), write it to ``path`` (PNG, :func:`write_png`) and close
    it."""
    draw(fig)
    write_png(fig, path)
    plt.close(fig)
    return path
