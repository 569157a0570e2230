"""The report's failure-anatomy section shows what the anatomy job wrote: one row per protocol
with its counts and onset quartiles, a figure slot per protocol, nothing without a summary."""

from __future__ import annotations

import json
import re
from pathlib import Path

from graspstab.labels.anatomy import summarise
from graspstab.report.anatomy import anatomy_parts

RULES = {"fail_distance": 0.01, "gap_s": 0.02, "slip_speed": 0.005, "saturation": 0.99,
         "spin": 0.5}  # fmt: skip


def _row(outcome: str, kind: str | None = None, onset: float = float("nan"),
         still: bool = False, moving: bool = False) -> dict:  # fmt: skip
    return {"outcome": outcome, "type": kind, "onset_s": onset, "still_window": still,
            "moving_at_settle": moving}  # fmt: skip


def _summary(tmp_path: Path, name: str, rows: list[dict], protocol: str) -> Path:
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps({"protocol": protocol, **summarise(rows), "rules": RULES}))
    return path


def _cells(html: str) -> list[list[str]]:
    body = html.split("<tbody>")[1].split("</tbody>")[0]
    return [re.findall(r"<td>(.*?)</td>", tr) for tr in body.split("<tr>")[1:]]


def test_one_row_per_protocol_with_the_job_s_counts(tmp_path: Path) -> None:
    ref = _summary(tmp_path, "ref", [
        _row("held"), _row("failed", "fingertip_slip", 0.0, moving=True),
        _row("failed", "link_slip", 2.0, still=True), _row("failed", "compliance", 4.0, still=True),
    ], "gravity")  # fmt: skip
    cf = _summary(tmp_path, "cf", [_row("held"), _row("held")], "perturb")
    html = "".join(anatomy_parts({"reference_summary": ref, "creep_free_summary": cf}))
    assert 'id="anatomy"' in html and "10 mm" in html and "5 mm/s" in html
    rows = _cells(html)
    assert rows[0][:8] == ["main run", "gravity", "4", "1", "3", "1", "2",
                           "2.00 (1.00-3.00)"]  # fmt: skip
    assert rows[0][8:] == ["1", "1", "0", "0", "1"]
    assert rows[1][:8] == ["creep-free benchmark", "perturb", "2", "2", "0", "0", "0", "n/a"]
    # no figure given: each protocol's slot says so, its id stays valid
    assert 'id="anatomy-figure"' in html and 'id="anatomy-figure-creep-free"' in html
    assert html.count("Not produced.") == 2


def test_nothing_without_a_summary() -> None:
    assert anatomy_parts(None) == [] and anatomy_parts({}) == []


def test_the_side_by_side_section_describes_the_benchmark_s_own_load() -> None:
    from graspstab.report.creep_free import load_sentence

    perturb = {"protocol": "perturb", "perturb": {"delay_s": [1.0, 5.0], "rate": [2.0, 10.0],
                                                  "ceiling": 30.0, "directions": "gravity_axes"}}
    text = load_sentence(perturb)
    assert "1-5 s" in text and "2-10 m g per second" in text and "gravity_axes" in text
    ramp = {"protocol": "ramp", "ramp": {"start_s": 1.0, "rate": 5.0, "ceiling": 30.0,
                                         "directions": "sphere", "path": "servo"}}
    assert "after 1 s" in load_sentence(ramp) and "path servo" in load_sentence(ramp)


def test_the_monitor_section_shows_the_early_warning_table() -> None:
    from graspstab.report.monitor import early_warning_part

    summary = {"early_warning": {"budget_per_s": 0.02, "ahead_s": 0.05, "monitors": {
        "proxy": {"threshold": {"threshold": 0.4321, "at_floor": True, "never_warns": False,
                                "false_per_s": 0.01},
                  "test": {"failing_after_still": 8, "warned_before_onset": 5, "warned_ahead": 4,
                           "warned_ahead_share": 0.5, "median_lead_s": 0.12,
                           "false_per_s": 0.03}}}}}  # fmt: skip
    html = "".join(early_warning_part(summary))
    assert "one per 50 s" in html and "50 ms" in html
    rows = _cells(html)
    assert rows[0] == ["friction-ratio proxy", "0.4321 (grid floor)", "0.010", "8", "5", "4",
                       "50.0 %", "0.120", "0.030"]
    assert early_warning_part({}) == []
