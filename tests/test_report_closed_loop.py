"""The report's "Closed loop" section from a summary of planted tables: the answer, the policy
table, the comparisons and the worse-grasp list; nothing when the closed loop is off."""

from __future__ import annotations

from pathlib import Path

import polars as pl
from test_closedloop_summary import planted

from graspstab.closedloop.summary import aggregate_closed_loop
from graspstab.report.closed_loop import WORSE_ROWS, closed_loop_section

CONFIG = {
    "closed_loop": {
        "enabled": True,
        "protocols": ["reference", "creep_free"],
        "policies": ["none", "always", "proxy", "gru"],
        "window_s": 0.01,
        "reflex": {"amount": 0.2, "rate": 4.0, "delay_s": 0.01, "release": "never"},
    }
}


def _files(tmp_path: Path, table: pl.DataFrame, protocol: str) -> dict[str, str]:
    src = tmp_path / f"{protocol}.parquet"
    table.write_parquet(src)
    out = tmp_path / protocol
    aggregate_closed_loop([str(src)], CONFIG["closed_loop"]["policies"], protocol,
                          {"resamples": 200, "level": 0.9, "seed": 1}, str(out))  # fmt: skip
    return {f"{protocol}_{k}": str(out / f"{k}.{'json' if k == 'summary' else 'parquet'}")
            for k in ("summary", "policies", "comparisons", "worse")}  # fmt: skip


def test_section_states_the_answer_and_tabulates_every_policy(tmp_path: Path) -> None:
    files = _files(tmp_path, planted(), "reference")
    html = closed_loop_section(files, CONFIG)
    assert 'id="closed-loop"' in html and 'id="closed-loop-reference"' in html
    assert "Under the reference protocol (gravity switch), over 12 test grasps" in html
    assert "creep-free" not in html.split("Policies:")[1]  # only the protocol with files
    for cell in ("<td>always</td>", "<td>6 of 6 (100.0 [100.0, 100.0])</td>", "<td>1</td>"):
        assert cell in html
    assert "[90 % CI]" in html
    assert "1 (grasp, policy) pairs where the policy drops a grasp that holds" in html
    assert "<td>always</td><td>b</td><td>11</td>" in html


def test_worse_list_is_capped_and_the_section_is_absent_when_off(tmp_path: Path) -> None:
    t = planted()
    many = pl.concat([t.with_columns(grasp_id=pl.col("grasp_id") + 100 * k) for k in range(40)])
    html = closed_loop_section(_files(tmp_path, many, "creep_free"), CONFIG)
    assert "40 (grasp, policy) pairs" in html and f"the first {WORSE_ROWS} are listed" in html
    assert html.count("<td>always</td><td>b</td>") == WORSE_ROWS
    off = {"closed_loop": dict(CONFIG["closed_loop"], enabled=False)}
    assert closed_loop_section(_files(tmp_path, t, "reference"), off) == ""
    assert closed_loop_section({}, CONFIG) == ""


def test_thresholds_are_stated_and_a_budget_at_the_floor_says_so(tmp_path: Path) -> None:
    """Rows carrying each monitor's threshold (the object jobs write it): the summary keeps one
    per policy and the section states them, a budget threshold at its grid floor flagged."""
    t = planted().with_columns(
        threshold=pl.when(pl.col("policy") == "gru").then(0.62)
        .when(pl.col("policy") == "proxy").then(0.2).otherwise(float("nan")),
        threshold_at_floor=pl.col("policy") == "proxy",
    )  # fmt: skip
    files = _files(tmp_path, t, "reference")
    html = closed_loop_section(files, CONFIG)
    assert "gru 0.62; proxy 0.2 (at the grid floor: the budget did not bind)" in html


def test_the_folds_part_stands_alone_when_only_the_folds_ran(tmp_path: Path) -> None:
    """closed_loop.folds without the fixed split's closed loop: the section shows the folds'
    part (its own heading, intervals over objects) and no fixed-split part."""
    files = _files(tmp_path, planted(), "creep_free")
    folds = {f"folds_{k}": v for k, v in files.items()}
    config = {"closed_loop": dict(CONFIG["closed_loop"], enabled=False,
                                  folds={"enabled": True, "grasps": 4})}  # fmt: skip
    html = closed_loop_section(folds, config)
    assert 'id="closed-loop-folds-creep_free"' in html and "each object's first 4 grasps" in html
    assert 'id="closed-loop-creep_free"' not in html
    assert closed_loop_section(folds, {"closed_loop": dict(config["closed_loop"],
                               folds={"enabled": False, "grasps": 4})}) == ""  # fmt: skip
