"""Prediction, not detection, in the report's sections: the still-now numbers a job wrote (planted
here) appear in the cross-validation, input-audit, split-robustness and two-protocol sections
beside the all-windows ones; an undefined one prints its reason, never 0; artefacts written before
the still-now metrics render without the still-now part."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
import pytest

from graspstab.common.io import read_json, write_json, write_parquet
from graspstab.evaluation import aggregate
from graspstab.evaluation.detection import ORACLE as EVALUATION_ORACLE
from graspstab.figures.artefacts import StudyArtefacts
from graspstab.figures.presentation import ORACLE, motion_reason
from graspstab.replay.outcomes import replay_outcomes
from graspstab.report import creep_free as cf
from graspstab.report import html as H
from graspstab.report.crossval import crossval_section, still_answer
from graspstab.report.headline import still_rows
from graspstab.report.sensing import audit_section
from graspstab.report.study_tables import splits_tables

NEVER = "undefined: no still-now test window becomes unstable"


def _cells(*cells: Any) -> str:
    """A regex of consecutive table cells ('*': any cell text)."""
    return "".join(
        "<td>[^<]*</td>" if c == "*" else f"<td>{re.escape(str(c))}</td>" for c in cells
    )


def _block(n: int, pos: int, auprc: float | None = None, auroc: float | None = None) -> dict:
    return {"n": n, "n_unstable": pos, "chance": pos / n if n else None, "auprc": auprc,
            "auroc": auroc}  # fmt: skip


def test_the_oracle_and_the_reasons() -> None:
    assert ORACLE == EVALUATION_ORACLE
    assert motion_reason(12, 0) == "no still-now test window becomes unstable"
    assert motion_reason(12, 0, "val") == "no still-now validation window becomes unstable"
    assert motion_reason(0, 0) == "the test split holds no still-now window"
    assert motion_reason(5, 5, part="moving") == "every moving-now test window becomes unstable"
    assert "written before them" in motion_reason(None, None)


# ----------------------------------------------------------------------------- crossval


def _png(path: Path) -> Path:
    from PIL import Image

    Image.new("RGB", (20, 20), (200, 100, 50)).save(path)
    return path


def _pooled(windows: int, unstable: int, auprc: float | None, auroc: float | None,
            chance: bool = False) -> dict[str, Any]:  # fmt: skip
    def ci(v: float | None) -> tuple[Any, Any]:
        return (None, None) if v is None else (v - 0.05, v + 0.05)

    row = {"windows": windows, "unstable": unstable, "grasps": 6, "seeds": 1,
           "auprc": auprc, "auprc_lo": ci(auprc)[0], "auprc_hi": ci(auprc)[1],
           "auroc": auroc, "auroc_lo": ci(auroc)[0], "auroc_hi": ci(auroc)[1]}  # fmt: skip
    return row | ({"chance": unstable / windows if windows else None} if chance else {})


def _paired(scorer: str, metric: str, diff: float | None, objects: int = 3) -> dict[str, Any]:
    if diff is None:
        return {"scorer": scorer, "metric": metric, "objects": 0, "mean_diff": None, "lo": None,
                "hi": None, "wins": 0, "losses": 0, "ties": 0, "sign_p": None,
                "verdict": "undefined"}  # fmt: skip
    return {"scorer": scorer, "metric": metric, "objects": objects, "mean_diff": diff,
            "lo": diff - 0.02, "hi": diff + 0.02, "wins": objects, "losses": 0, "ties": 0,
            "sign_p": 0.25, "verdict": "learned better" if diff - 0.02 > 0 else "not resolved"}


def _crossval(tmp_path: Path, still: bool, **extra: Any) -> tuple[dict, dict]:
    """A k-fold study's files as aggregate_crossval writes them (``still``: with the still-now
    keys), and the configuration the section reads."""
    objects = ["001_a", "002_b", "003_c"]
    summary: dict[str, Any] = {
        "protocol": "reference", "objects": 3, "tested_objects": objects,
        "untested_objects": [], "folds": 3, "scorers": ["gru", "proxy"],
        "bootstrap": {"resamples": 100, "level": 0.95, "seed": 0},
        "pooled": {"gru": _pooled(90, 30, 0.8123, 0.9), "proxy": _pooled(90, 30, 0.7, 0.75)},
        "fold_mean": {"gru": {"auprc": 0.8, "auprc_std": 0.01},
                      "proxy": {"auprc": 0.7, "auprc_std": 0.02}},
        "paired": [_paired("gru", "auprc", 0.1), _paired("gru", "auroc", 0.15)],
        "variants": [], "thresholds": [],
        "answer": "Under the reference protocol, on unseen objects every learned model beats "
                  "the friction-ratio proxy (planted).",
    }  # fmt: skip
    if still:
        summary |= {
            "pooled_still": {"gru": _pooled(40, 8, 0.4567, 0.6789, True),
                             "proxy": _pooled(40, 8, 0.3012, 0.55, True),
                             ORACLE: _pooled(40, 8, 0.2, 0.5, True)},
            "oracle": _pooled(90, 30, 0.9321, 0.95, True),
            "paired_still": [_paired("gru", "auprc", 0.156), _paired("gru", "auroc", 0.12)],
        }  # fmt: skip
    summary |= extra
    out = tmp_path / "study"
    write_json(out / "summary.json", summary)
    per_object = pl.DataFrame([
        {"scorer": s, "object": o, "mass": 0.1, "size": 0.05, "shape": "box", "windows": 30,
         "unstable": 10, "grasps": 2, "auprc": 0.8, "auprc_lo": 0.7, "auprc_hi": 0.9}
        for s in ("gru", "proxy") for o in objects
    ])  # fmt: skip
    write_parquet(out / "per_object.parquet", per_object)
    files = {"reference_summary": out / "summary.json",
             "reference_per_object": out / "per_object.parquet",
             "reference_figure": _png(tmp_path / "f.png")}  # fmt: skip
    if still:
        # one object's still-now test windows never become unstable: its AUPRC undefined
        never = pl.col("object") == "003_c"
        write_parquet(out / "per_object_still.parquet", per_object.with_columns(
            pl.when(never).then(None).otherwise(0.6123).alias("auprc"),
            pl.when(never).then(None).otherwise(0.55).alias("auprc_lo"),
            pl.when(never).then(None).otherwise(0.65).alias("auprc_hi"),
            pl.when(never).then(0).otherwise(4).alias("unstable"),
        ))  # fmt: skip
        files["reference_per_object_still"] = out / "per_object_still.parquet"
    config = {"crossval": {"enabled": True, "k": 3, "variants": [], "variant_families": [],
                           "window_s": 0.01, "seeds": [42], "protocols": ["reference"]},
              "objects": {"items": dict.fromkeys(objects, {})}}  # fmt: skip
    return files, config


def test_crossval_still_now_tables_and_answer(tmp_path: Path) -> None:
    files, config = _crossval(tmp_path, still=True)
    html = crossval_section(files, config)
    # the oracle's row (all windows) joins the pooled table, after the scorers
    assert re.search(_cells("persistence oracle (reads object motion: a reference line)", 90,
                            30, 6, "93.2 [88.2, 98.2]", "95.0 [90.0, 100.0]", "—"), html)
    still = html[html.index('id="crossval-still-reference"') :]
    for row in [
        ("gru", 40, 8, 6, "20.0", "45.7 [40.7, 50.7]", "67.9 [62.9, 72.9]"),
        ("proxy", 40, 8, 6, "20.0", "30.1 [25.1, 35.1]", "55.0 [50.0, 60.0]"),
        ("persistence oracle (reads object motion: a reference line)", 40, 8, 6, "20.0",
         "20.0 [15.0, 25.0]", "50.0 [45.0, 55.0]"),
    ]:  # fmt: skip
        assert re.search(_cells(*row), still), row
    assert re.search(_cells("gru", "AUPRC", 3, "+15.6 [+13.6, +17.6]"), still)
    # per object: an object whose still-now test windows hold no unstable one says so
    assert re.search(_cells("001_a", 30, 4, "61.2 [55.0, 65.0]", "61.2 [55.0, 65.0]"), still)
    assert re.search(_cells("003_c", 30, 0, NEVER, NEVER), still)
    # the answer on still-now windows, from paired_still, beside the all-windows answer
    answer = still_answer(read_json(files["reference_summary"]), "reference")
    assert answer.startswith("Under the reference protocol, on the still-now test windows")
    assert "every learned model beats the friction-ratio proxy" in answer
    assert "gru +15.6 points [+13.6, +17.6] over 3 objects" in answer
    top = html[: html.index("Pooled test metrics")]
    assert "(planted)" in top and answer in top.replace("&#x27;", "'")


def test_crossval_still_now_undefined_and_the_jobs_answer(tmp_path: Path) -> None:
    """No still-now test window becomes unstable: every still-now metric is undefined with the
    reason; a summary with ``answer_still`` is printed as written."""
    files, config = _crossval(tmp_path, still=True, pooled_still={
        "gru": _pooled(40, 0, None, None, True), "proxy": _pooled(40, 0, None, None, True),
        ORACLE: _pooled(40, 0, None, None, True)},
        paired_still=[_paired("gru", "auprc", None), _paired("gru", "auroc", None)])  # fmt: skip
    html = crossval_section(files, config)
    assert re.search(_cells("gru", 40, 0, 6, "0.0", NEVER, NEVER), html)
    assert ("the comparison on still-now test windows is undefined: no still-now test window "
            "becomes unstable") in html  # fmt: skip
    files, config = _crossval(tmp_path, still=True, answer_still="Planted still-now answer.")
    assert "<strong>Planted still-now answer.</strong>" in crossval_section(files, config)


def test_crossval_says_what_the_anatomy_misses_only_where_the_models_do_not_win(
    tmp_path: Path,
) -> None:
    """Where a family does not beat the proxy on still-now windows, the protocol's failure
    anatomy says how its failures begin (counts and shares from the summary); where every
    family wins, nothing is added."""
    from graspstab.report.anatomy import missing_signal

    anatomy = tmp_path / "anatomy.json"
    write_json(anatomy, {"protocol": "perturb", "failed": 20, "types": {
        "fingertip_slip": 5, "link_slip": 12, "compliance": 2, "rotation": 1,
        "servo_saturation": 0}})  # fmt: skip
    text = missing_signal(read_json(anatomy))
    assert "of the 20 grasps that fail after settling, 5 (25 %) fingertip slip" in text
    assert "15 (75 %) begin where no sensor is" in text
    lost = [_paired("gru", "auprc", 0.0), _paired("gru", "auroc", 0.0)]
    files, config = _crossval(tmp_path, still=True, paired_still=lost)
    html = crossval_section(files, config, {"reference_summary": anatomy})
    assert H.esc(text) in html
    files, config = _crossval(tmp_path, still=True)  # gru wins on still-now windows
    assert "begin where no sensor is" not in crossval_section(
        files, config, {"reference_summary": anatomy})


def test_crossval_without_the_still_now_keys(tmp_path: Path) -> None:
    files, config = _crossval(tmp_path, still=False)
    html = crossval_section(files, config)
    assert "still-now" not in html and "still now" not in html and "persistence" not in html
    assert re.search(_cells("gru", 90, 30, 6, "81.2 [76.2, 86.2]"), html)


# ---------------------------------------------------------------------------- input audit


def _audit(tmp_path: Path, still: bool) -> str:
    """The input audit's summary.json as aggregate_inputs writes it, from two seeds' records."""
    records, keys = [], []
    for s, (a, b) in {"forces": (0.41, 0.43), "normal": (None, None)}.items():
        for seed, v in ((42, a), (43, b)):
            metrics = {"n": 50, "n_unstable": 10, "auprc": 0.9, "auroc": 0.9}
            rec: dict[str, Any] = {"family": "lstm", "seed": seed, "best_epoch": 1,
                                   "threshold": {"rule": "min_recall", "threshold": 0.5},
                                   "val": metrics, "test": metrics}  # fmt: skip
            if still:  # the normal-only set's still-now test windows never become unstable
                rec |= {"test_still": _block(20, 5, v, 0.7) if v else _block(20, 0),
                        "val_still": _block(10, 0)}  # fmt: skip
            records.append(rec)
            keys.append({"input_set": s})
    runs = aggregate.run_rows(records, keys)
    if not still:
        runs = runs.select(c for c in runs.columns if not c.startswith(("still_", "moving_")))
    summary = aggregate.mean_std(runs, ["input_set", "family", "split"])
    shapes = [{"input_set": s, "family": "lstm", "inputs": w, "parameters": 1000 + w}
              for s, w in (("forces", 10), ("normal", 5))]  # fmt: skip
    write_json(tmp_path / "summary.json", {"summary": summary.to_dicts(), "shapes": shapes})
    return audit_section({"summary": str(tmp_path / "summary.json")})


def test_audit_still_now_columns(tmp_path: Path) -> None:
    html = _audit(tmp_path, still=True)
    std = 100 * np.std([0.41, 0.43], ddof=1)
    assert re.search(_cells("*", 10, "90.0 ± 0.0", "1,010", f"42.0 ± {std:.1f}", 20, 5, "25.0"),
                     html)  # fmt: skip
    assert re.search(_cells("normal only", 5, "90.0 ± 0.0", "1,005", NEVER, 20, 0, "0.0"), html)
    assert "LSTM test AUPRC, still now (%)" in html and "early warning proper" in html


def test_audit_without_the_still_now_columns(tmp_path: Path) -> None:
    html = _audit(tmp_path, still=False)
    assert "still now" not in html and re.search(_cells("normal only", 5, "90.0 ± 0.0"), html)


# ---------------------------------------------------------------------- split robustness


def test_split_robustness_still_now(tmp_path: Path) -> None:
    hard = {"assignment": 3, "val_objects": "a", "test_objects": "b", "auprc": 0.6,
            "auprc_std": 0.01, "seeds": 2}  # fmt: skip
    base = {"assignments": 4, "defined": 4, "mean": 0.7, "std": 0.1, "median": 0.7, "min": 0.6,
            "fixed_split": 0.8}  # fmt: skip
    old = splits_tables({**base, "hardest": [hard]}, "lstm")
    assert "still now" not in old
    still = {"assignments": 4, "defined": 3, "mean": 0.3456, "std": 0.05, "median": 0.33,
             "min": 0.2, "fixed_split": None}  # fmt: skip
    hard_still = {**hard, "still_auprc": None, "still_auprc_std": None, "still_n": 12,
                  "still_n_unstable": 0, "still_chance": 0.0}  # fmt: skip
    html = splits_tables({**base, "still": still, "hardest": [hard_still]}, "lstm")
    assert old.split("</table>")[0] == html.split("</table>")[0]  # the all-windows table as it was
    assert re.search(_cells("mean ± std", "34.56 ± 5.00 %"), html)
    assert re.search(_cells("assignments", "4 (3 defined)"), html)
    assert "undefined: the fixed split&#x27;s still-now test windows hold no unstable" in html
    assert re.search(_cells(3, "a", "b", "60.00 ± 1.00 %", 2, NEVER, 12, 0, "0.00 %"), html)
    none = splits_tables({**base, "still": {**still, "defined": 0, "mean": None, "std": None,
                                            "median": None, "min": None}, "hardest": []}, "lstm")
    assert "undefined: none of 4 assignments has a defined still-now test AUPRC" in none


# ------------------------------------------------------------------ two protocols side by side


def _benchmark(root: Path, name: str, still: bool, test_still: dict | None = None) -> cf.Benchmark:
    """One protocol's artefacts, its baseline and sweep studies written from two seeds' records
    (``still``: with the still-now blocks; ``test_still``: the families' still-now test block)."""
    root.mkdir(parents=True)
    splits = {s: {"grasps": 2, "stable": 30, "unstable": 10} for s in ("train", "val", "test")}
    write_json(root / "dataset.json", {"splits": splits, "objects": {"o": splits}})
    q = {"q50": 0.001}
    write_json(root / "speeds.json", {"box_creep": {"speed": 0.001}, "held_creep": q,
                                      "target_speed": {"unstable": q}})  # fmt: skip
    rng = np.random.default_rng(0)
    rows = [{"grasp_id": g, "object": "o", "shard": 0, "stop_reason": "completed",
             "diverged": False, "held_at_end": True, "max_penetration": 0.001,
             "duration_s": 1.0, "ramp_slip_s": float(rng.uniform(1, 2)),
             "contact_loss_s": float("nan"), "ramp_peak_load_mg": 1.0}
            for g in range(3)]  # fmt: skip
    write_parquet(root / "outcomes.parquet", replay_outcomes(pl.DataFrame(rows)))
    metrics = {"n": 40, "n_unstable": 10, "auprc": 0.9, "auroc": 0.9, "tp": 8, "fp": 2, "fn": 2,
               "tn": 28, "precision": 0.8, "recall": 0.8, "f1": 0.8}  # fmt: skip
    records, sweep = [], []
    for f in ("cnn", "gru", "lstm"):
        for seed in (42, 43):
            rec: dict[str, Any] = {"family": f, "seed": seed, "best_epoch": 1,
                                   "threshold": {"rule": "min_recall", "threshold": 0.5},
                                   "val": metrics, "test": metrics}  # fmt: skip
            if still:
                rec |= {"test_still": test_still or _block(12, 3, 0.5 + 0.01 * seed - 0.42,
                                                           0.6),
                        "val_still": _block(10, 2, 0.3, 0.6)}  # fmt: skip
            records.append(rec)
            sweep.append({**rec, "window_s": 0.01})
    s = root / "studies"
    for study, recs, by, keys in (
        ("baseline", records, ["family", "split"], [{} for _ in records]),
        ("sweep", sweep, ["family", "window_s", "split"], [{"window_s": 0.01} for _ in sweep]),
    ):
        runs = aggregate.run_rows(recs, keys)
        if not still:
            runs = runs.select(c for c in runs.columns if not c.startswith(("still_", "moving_")))
        write_parquet(s / study / "summary_defined.parquet", aggregate.seed_summary(runs, by))
    proxy: dict[str, Any] = {"test": {"auprc": 0.7, "auroc": 0.72, "n": 40, "n_unstable": 10}}
    if still:
        proxy |= {"test_still": _block(12, 3, 0.3333, 0.5),
                  ORACLE: {"test": _block(40, 10, 0.95, 0.97), "test_still": _block(12, 3, 0.25,
                                                                                    0.5)}}
    write_json(s / "proxy.json", proxy)
    studies = StudyArtefacts(baseline_summary_defined=s / "baseline" / "summary_defined.parquet",
                             sweep_summary_defined=s / "sweep" / "summary_defined.parquet",
                             proxy=s / "proxy.json")  # fmt: skip
    return cf.Benchmark(name, root / "dataset.json", root / "speeds.json",
                        root / "outcomes.parquet", studies, sweep_windows_s=(0.01,))


RAMP = {"protocol": "ramp", "ramp": {"start_s": 1.0, "rate": 0.5, "ceiling": 3.0,
                                     "directions": "gravity", "path": "ramp"}}  # fmt: skip


def test_two_protocols_side_by_side_still_now(tmp_path: Path) -> None:
    main = _benchmark(tmp_path / "main", "gravity", still=True)
    ramp = _benchmark(tmp_path / "ramp", "load ramp", still=True, test_still=_block(12, 0))
    html = cf.creep_free_section(main, ramp, RAMP)
    assert re.search(_cells("CNN test AUPRC, still now", "50.50 ± 0.71 %", NEVER), html)
    assert re.search(_cells("friction-ratio proxy test AUPRC, still now", "33.33 %", "33.33 %"),
                     html)  # fmt: skip
    assert re.search(_cells("persistence oracle test AUPRC (reads object motion: a reference "
                            "line)", "95.00 %", "95.00 %"), html)  # fmt: skip
    assert re.search(_cells("persistence oracle test AUPRC, still now", "25.00 %", "25.00 %"),
                     html)  # fmt: skip
    assert re.search(_cells("still-now test windows (unstable; chance AUPRC)",
                            "12 (3; 25.0 %)", "12 (3; 25.0 %)"), html)  # fmt: skip
    # the sweep: validation AUPRC as before, then on the still-now validation windows
    assert re.search(_cells("0.01", "CNN", "90.000 ± 0.000 %", "90.000 ± 0.000 %",
                            "30.000 ± 0.000 %", "30.000 ± 0.000 %"), html)  # fmt: skip
    assert "gravity: still now (validation)" in html and "early warning proper" in html


@pytest.mark.parametrize("either", [True, False])
def test_two_protocols_side_by_side_before_the_still_now_metrics(
    tmp_path: Path, either: bool
) -> None:
    """Both protocols' artefacts written before the still-now metrics: the section without its
    still-now rows; one protocol's: its cells say the metrics were not recorded."""
    main = _benchmark(tmp_path / "main", "gravity", still=either)
    ramp = _benchmark(tmp_path / "ramp", "load ramp", still=False)
    html = cf.creep_free_section(main, ramp, RAMP)
    assert re.search(_cells("CNN test AUPRC", "90.00 ± 0.00 %", "90.00 ± 0.00 %"), html)
    if either:
        assert re.search(_cells("CNN test AUPRC, still now", "50.50 ± 0.71 %",
                                "undefined: no still-now metrics recorded (an artefact written "
                                "before them)"), html)  # fmt: skip
    else:
        assert "still now" not in html and "persistence" not in html
        assert still_rows(main.studies) == []
