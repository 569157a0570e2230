"""The one matplotlib setup of every plotting module, so that figures are drawn headless, left
empty and written to disk the same way everywhere: the Agg backend (no display on a cluster
node; chosen here, once, before pyplot loads), the "no data" panel and the atomic PNG save.
Plotting modules import ``plt``, :func:`no_data` and :func:`save` from here and never set up
matplotlib themselves (tests/test_plotting.py checks)."""

from __future__ import annotations

import os
from typing import IO, Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.text import Text  # noqa: E402

from graspstab.common.io import save_figure  # noqa: E402

__all__ = ["no_data", "plt", "save"]


def no_data(
    ax: Axes,
    text: str = "no data",
    *,
    color: str | None = "0.3",
    fontsize: float | None = 10,
    va: str = "center",
    wrap: bool = True,
    axis_off: bool = False,
) -> Text:
    """Say in the middle of the panel that there is nothing to draw (``axis_off``: and hide its
    frame and ticks). ``color`` or ``fontsize`` None is matplotlib's default text style."""
    if axis_off:
        ax.set_axis_off()
    return ax.text(0.5, 0.5, text, ha="center", va=va, transform=ax.transAxes, color=color,
                   fontsize=fontsize, wrap=wrap)  # fmt: skip


def save(
    fig: Figure,
    path: str | os.PathLike[str] | IO[bytes],
    dpi: float,
    *,
    tight: bool = False,
    **savefig: Any,
) -> None:
    """Write ``fig`` as a PNG at ``dpi`` and close it, also when writing fails. A path is written
    atomically (a temporary file beside it, renamed into place); an open binary stream (a figure
    kept in memory) directly. ``tight`` crops the margins to the drawn content; other keywords go
    to ``savefig`` (e.g. ``facecolor``)."""
    options = {"format": "png", "dpi": dpi, **savefig}
    if tight:
        options["bbox_inches"] = "tight"
    try:
        if hasattr(path, "write"):
            fig.savefig(path, **options)
        else:
            save_figure(path, fig, **options)
    finally:
        plt.close(fig)
