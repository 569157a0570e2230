"""The one figure setup (graspstab.common.plotting): no other module selects a backend or imports
pyplot, the "no data" panel draws exactly what the hand-written fallbacks it replaced drew, and
the PNG save is atomic and closes the figure."""

from __future__ import annotations

import ast
import io
from pathlib import Path

import matplotlib
import numpy as np
import pytest
from PIL import Image

from graspstab.common.plotting import no_data, plt, save
from tests.conftest import REPO

PACKAGE = REPO / "src" / "graspstab"
SETUP = PACKAGE / "common" / "plotting.py"
PLOTTING_MODULES = [
    "objects/figure.py", "hand/figure.py", "synthesis/figure.py", "synthesis/figure_draw.py",
    "replay/figure.py", "labels/figure.py", "labels/speed_figure.py", "monitor/figures.py",
    "closedloop/figures.py", "report/dag.py", "figures/common.py",
]  # fmt: skip
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _matplotlib_setup(path: Path) -> list[str]:
    """Where ``path`` selects a backend (``matplotlib.use``) or imports pyplot itself."""
    tree = ast.parse(path.read_text(), filename=str(path))
    aliases = set()  # names bound to the matplotlib package (import matplotlib [as mpl])
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name == "matplotlib":
                    aliases.add(a.asname or a.name)
                elif a.name == "matplotlib.pyplot":
                    found.append(f"line {node.lineno}: import matplotlib.pyplot")
        elif isinstance(node, ast.ImportFrom) and node.module:
            if node.module == "matplotlib.pyplot" or (
                node.module == "matplotlib" and {a.name for a in node.names} & {"pyplot", "use"}
            ):
                found.append(f"line {node.lineno}: from {node.module} import ...")
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr == "use"
            and isinstance(node.func.value, ast.Name)
            and node.func.value.id in aliases
        ):
            found.append(f"line {node.lineno}: {node.func.value.id}.use(...)")
    return sorted(found, key=lambda where: int(where.split()[1].rstrip(":")))


def test_only_common_plotting_sets_up_matplotlib() -> None:
    offenders = {
        str(path.relative_to(PACKAGE)): where
        for path in sorted(PACKAGE.rglob("*.py"))
        if path != SETUP and (where := _matplotlib_setup(path))
    }
    assert not offenders, f"set up matplotlib through graspstab.common.plotting: {offenders}"
    setup = _matplotlib_setup(SETUP)
    assert len(setup) == 2 and "use(" in setup[0] and "pyplot" in setup[1], setup  # Agg first
    assert matplotlib.get_backend().lower() == "agg"


@pytest.mark.parametrize("module", PLOTTING_MODULES)
def test_plotting_modules_go_through_common_plotting(module: str) -> None:
    tree = ast.parse((PACKAGE / module).read_text())
    imported = {
        f"{node.module}.{a.name}" if node.module == "graspstab.common" else node.module
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom)
        for a in node.names
    }
    assert "graspstab.common.plotting" in imported, module


# ----------------------------------------------------------------------------------- no_data


def _pixels(fig: plt.Figure) -> np.ndarray:
    buf = io.BytesIO()
    save(fig, buf, 40)
    return np.asarray(Image.open(buf).convert("RGBA"))


def test_no_data_writes_its_text_on_an_empty_panel() -> None:
    fig, ax = plt.subplots()
    text = no_data(ax, "nothing to show")
    assert list(ax.texts) == [text] and text.get_text() == "nothing to show"
    assert text.get_position() == (0.5, 0.5) and text.get_transform() is ax.transAxes
    assert (text.get_ha(), text.get_va()) == ("center", "center")
    assert (text.get_color(), text.get_fontsize(), text.get_wrap()) == ("0.3", 10, True)
    assert not (ax.lines or ax.patches or ax.collections or ax.images)  # no data drawn
    assert ax.axison  # by default the panel keeps its frame and ticks (a figure's axis labels)
    plt.close(fig)

    fig, ax = plt.subplots()
    no_data(ax, "nothing to show", axis_off=True)
    assert not ax.axison  # as the hand-written fallbacks did (set_axis_off, axis("off"))
    blank, _ = plt.subplots()
    blank.axes[0].set_axis_off()
    # the rendering differs from a blank panel only by the text: no frame, ticks or labels
    diff = np.any(_pixels(fig) != _pixels(blank), axis=-1)
    rows, cols = np.nonzero(diff)
    h, w = diff.shape
    assert abs(rows.mean() - h / 2) < 0.1 * h and abs(cols.mean() - w / 2) < 0.1 * w
    assert diff.sum() < 0.05 * h * w


def _old_chapter4(ax: plt.Axes, text: str) -> None:
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, color="0.3",
            fontsize=10, wrap=True)  # fmt: skip


def _old_labels(ax: plt.Axes, text: str) -> None:
    ax.text(0.5, 0.5, text, ha="center", va="center")
    ax.set_axis_off()


def _old_timeline(ax: plt.Axes, text: str) -> None:
    ax.axis("off")
    ax.text(0.5, 0.5, text, ha="center")


PLAIN = {"color": None, "fontsize": None, "wrap": False, "axis_off": True}  # matplotlib's style


@pytest.mark.parametrize(
    ("old", "style", "figsize"),
    [
        (_old_chapter4, {}, (7, 2.2)),
        (_old_labels, PLAIN, (6, 1.5)),
        (_old_timeline, {**PLAIN, "va": "baseline"}, (8, 7)),
    ],
    ids=["chapter4", "labels", "monitor-closedloop"],
)
def test_no_data_draws_what_the_fallback_it_replaced_drew(old, style, figsize) -> None:
    """Pixel for pixel: the modules' own empty-panel fallbacks became no_data calls."""
    text = "no closed-loop run to draw " * 4  # long enough that the wrapped one wraps
    before, ax = plt.subplots(figsize=figsize)
    old(ax, text)
    after, ax = plt.subplots(figsize=figsize)
    no_data(ax, text, **style)
    np.testing.assert_array_equal(_pixels(before), _pixels(after))


# -------------------------------------------------------------------------------------- save


def _figure() -> plt.Figure:
    fig, ax = plt.subplots(figsize=(2, 1.5))
    ax.plot([0, 1, 2], [1, 0, 1])
    return fig


def test_save_writes_a_png_atomically_and_closes_the_figure(tmp_path: Path) -> None:
    fig = _figure()
    target = tmp_path / "out" / "f.png"
    assert save(fig, target, 50) is None
    assert not plt.fignum_exists(fig.number)
    assert sorted(p.name for p in target.parent.iterdir()) == ["f.png"]  # no temporary file
    data = target.read_bytes()
    assert data.startswith(PNG_SIGNATURE)
    with Image.open(target) as img:
        img.verify()
    with Image.open(target) as img:
        assert img.format == "PNG" and img.size == (100, 75)  # figsize x dpi, uncropped

    cropped = tmp_path / "g.png"
    save(_figure(), cropped, 50, tight=True)
    with Image.open(cropped) as img:
        assert img.size != (100, 75)
    buf = io.BytesIO()
    save(_figure(), buf, 50)  # a stream: the same bytes, in memory
    assert buf.getvalue() == data


def test_a_failing_save_leaves_no_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    fig = _figure()

    def half_written(fname: object, **kwargs: object) -> None:
        Path(fname).write_bytes(PNG_SIGNATURE)  # a truncated PNG, then the failure
        raise OSError("disk full")

    monkeypatch.setattr(fig, "savefig", half_written)
    target = tmp_path / "f.png"
    with pytest.raises(OSError, match="disk full"):
        save(fig, target, 50)
    assert not target.exists()
    assert list(tmp_path.iterdir()) == []  # nor its temporary file
    assert not plt.fignum_exists(fig.number)  # closed all the same
