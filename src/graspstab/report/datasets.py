"""The report's "Window datasets" section: the labelling jobs' dataset summaries (windows per
split, class and object, cf. 4.1.1) as written, and the window figure (fig. 3.8)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from graspstab.common.io import read_json
from graspstab.report import html as H


def dataset_parts(
    baseline: Path | None, sweep: Sequence[Path] | None, figures: Mapping[str, Path]
) -> list[str]:
    """Window counts per split and class (cf. 4.1.1), per object, and per sweep window."""
    if baseline is None:
        return []
    base = read_json(baseline)
    head = ["", *[f"{s} {c}" for s in ("train", "val", "test") for c in ("stable", "unstable")]]

    def row(name: str, counts: dict) -> list:
        return [name, *[counts[s][c] for s in ("train", "val", "test")
                        for c in ("stable", "unstable")]]  # fmt: skip

    rows = [row("all objects", base["splits"])]
    rows += [row(o, c) for o, c in base["objects"].items()]
    window = (
        H.image(figures["window"], "window illustration", (
            "One sample's observation window, offset and horizon (dashed) on its replay's "
            "fingertip forces, with stable (green) and unstable (red) periods (cf. fig. 3.8)."),
            "window", "Window (fig. 3.8)")
        if "window" in figures
        else H.missing_figure("window", "Window (fig. 3.8)", "Not produced in this run.")
    )  # fmt: skip
    parts = [
        H.heading(2, "datasets", "Window datasets"),
        window,
        H.heading(3, "dataset-counts", "Dataset counts (section 4.1.1)"),
        H.table(head, rows, caption=(
            f"Baseline dataset ({base['window_s']:g} s windows, 3.3): labelled windows per split "
            "and class (cf. section 4.1.1)")),
    ]  # fmt: skip
    if sweep:
        sums = sorted((read_json(p) for p in sweep), key=lambda d: d["window_s"])
        parts.append(H.table(
            ["window [s]", "windows", "train unstable", "val unstable", "test unstable"],
            [[f"{d['window_s']:g}", d["windows"],
              *[d["splits"][s]["unstable"] for s in ("train", "val", "test")]] for d in sums],
            caption="Sweep datasets, trimmed from the longest window (same end, label, split)",
        ))  # fmt: skip
    return parts
