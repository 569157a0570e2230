"""benchmarks/perturb_defaults.py: its labelling changes and its per-variant figures against
hand counts on constructed rows."""

from __future__ import annotations

import importlib.util

import pytest

from tests.conftest import REPO

spec = importlib.util.spec_from_file_location(
    "perturb_defaults", REPO / "benchmarks" / "perturb_defaults.py"
)
pd = importlib.util.module_from_spec(spec)
spec.loader.exec_module(pd)


def test_a_variant_composes_the_benchmark_under_the_disturbance() -> None:
    replay, labels, splits = pd.variant_config("creep_free.seconds=10 replay.perturb.rate=[5,20]")
    assert replay["protocol"] == "perturb" and replay["perturb"]["rate"] == [5, 20]
    assert replay["steps"] == round(10 / replay["timestep"])
    assert replay["contact"]["name"] == "strict" and splits
    ramp, _, _ = pd.variant_config("creep_free.load=ramp")
    assert ramp["protocol"] == "ramp"


def test_labelling_changes_keys_and_refuses_unknown_ones() -> None:
    labels = {"source": "object_speed", "horizon_s": 0.15, "form": "share"}
    out = pd.labelling(labels, "form=event horizon_s=1.0")
    assert out == {"source": "object_speed", "horizon_s": 1.0, "form": "event"}
    assert pd.labelling(labels, "") == labels
    with pytest.raises(SystemExit, match="no key 'horizon'"):
        pd.labelling(labels, "horizon=1")


def test_report_counts_late_failures_types_and_still_now_shares() -> None:
    def row(split, outcome, kind=None, onset=float("nan"), still=False, sw=0, sp=0):
        return {"split": split, "outcome": outcome, "type": kind, "onset_s": onset,
                "still_window": still, "": {"still_windows": sw, "still_positive": sp,
                                            "windows": sw + 1, "positive": sp}}  # fmt: skip

    rows = [row("train", "held", sw=10), row("train", "failed", "link_slip", 2.0, True, 8, 2),
            row("val", "failed", "fingertip_slip", 0.2, True, 4, 1),
            row("test", "failed", "compliance", 1.0, False, 0, 0)]  # fmt: skip
    out = pd.report("v", rows, 0.5, ("",))
    assert (out["usable"], out["failed"], out["failed_after_still"]) == (4, 3, 1)
    assert out["failed_after_still_share"] == 0.25
    assert out["types"]["link_slip"] == 1 and out["types_after_still"]["fingertip_slip"] == 0
    train = out["still_now"]["benchmark labels"]["train"]
    assert (train["still_windows"], train["positive"], train["share"]) == (18, 2, 0.111)
    assert out["still_now"]["benchmark labels"]["test"]["share"] is None
