"""The closed loop's figures from planted summaries and timelines: the best-ranked grasp is drawn,
both figures are written (and a run without a sweep or a run says so), the report embeds them."""

from __future__ import annotations

from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import polars as pl
from test_closedloop_summary import planted

from graspstab.closedloop.closed_loop import write_timeline
from graspstab.closedloop.figures import best_timeline, plot_closed_loop
from graspstab.closedloop.summary import aggregate_closed_loop
from graspstab.report.closed_loop import closed_loop_section

DT = 5e-4


def traces(n: int, slide_from: int | None) -> dict[str, np.ndarray]:
    velocity = np.zeros((n, 3), np.float32)
    if slide_from is not None:
        velocity[slide_from:, 0] = 0.01
    return {
        "normal": np.ones((n, 5), np.float32),
        "velocity": velocity,
        "reflex": np.linspace(0, 0.2, n, dtype=np.float32),
    }


def timeline(tmp_path: Path, table: pl.DataFrame, obj: str, gid: int) -> Path:
    path = tmp_path / f"{obj}.npz"
    write_timeline(path, table, {(gid, "none"): traces(400, 100), (gid, "gru"): traces(400, None)})
    return path


def test_both_figures_from_a_summary_and_the_best_ranked_timeline(tmp_path: Path) -> None:
    t = planted().with_columns(
        parameter=pl.lit(""), value=pl.lit(float("nan")), onset_s=pl.lit(0.05)
    )
    variant = t.filter(pl.col("policy") == "proxy").with_columns(
        policy=pl.lit("proxy@amount=0.1"), parameter=pl.lit("amount"), value=pl.lit(0.1)
    )
    t.vstack(variant).write_parquet(tmp_path / "all.parquet")
    pols = ["none", "always", "proxy", "gru"]
    aggregate_closed_loop(
        [str(tmp_path / "all.parquet")],
        pols,
        "creep_free",
        {"resamples": 100, "level": 0.95, "seed": 0},
        str(tmp_path / "s"),
    )
    # grasp 10: gru fired on a holding grasp (rank 1); grasp 7: failing, gru silent (rank 2)
    paths = [timeline(tmp_path, t, "b", 10), timeline(tmp_path, t, "a", 7)]
    arrays, meta = best_timeline(paths)
    assert (meta["grasp_id"], meta["rank"]) == (7, 2) and "reflex/reflex" in arrays
    out = {k: tmp_path / f"{k}.png" for k in ("tradeoff", "timeline")}
    plot_closed_loop(
        tmp_path / "s", paths, "creep_free", 0.0012, DT, out["tradeoff"], out["timeline"], dpi=50
    )
    for png in out.values():
        assert mpimg.imread(png).shape[0] > 100
    files = {
        f"creep_free_{k}": str(tmp_path / "s" / f"{k}.{'json' if k == 'summary' else 'parquet'}")
        for k in ("summary", "policies", "comparisons", "worse", "tradeoff")
    }
    files |= {f"creep_free_{k}_figure": str(p) for k, p in out.items()}
    config = {
        "closed_loop": {
            "enabled": True,
            "protocols": ["creep_free"],
            "policies": pols,
            "window_s": 0.01,
            "reflex": {"amount": 0.2, "rate": 4.0, "delay_s": 0.01, "release": "never"},
        }
    }
    html = closed_loop_section(files, config)
    assert html.count("data:image/png;base64,") == 2
    assert (
        "<td>proxy</td><td>amount = 0.1</td>" in html and "<td>proxy</td><td>default</td>" in html
    )


def test_without_a_sweep_or_a_run_the_figures_say_so(tmp_path: Path) -> None:
    planted().write_parquet(tmp_path / "all.parquet")
    aggregate_closed_loop(
        [str(tmp_path / "all.parquet")],
        ["none", "gru"],
        "reference",
        {"resamples": 100, "level": 0.95, "seed": 0},
        str(tmp_path / "s"),
    )
    empty = tmp_path / "empty.npz"
    write_timeline(empty, planted(), {})
    assert best_timeline([empty]) == ({}, {})
    out = [tmp_path / "a.png", tmp_path / "b.png"]
    plot_closed_loop(tmp_path / "s", [empty], "reference", 0.0012, DT, *out, dpi=50)
    assert all(mpimg.imread(p).shape[0] > 50 for p in out)
