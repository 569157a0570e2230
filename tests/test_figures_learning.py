"""Tests of the chapter-4 figures and report section: a small synthetic results tree in the
studies' formats (written by the studies' own aggregation code), including the quick profile's
undefined validation metrics, must give valid, non-trivial PNGs and a section that embeds them
beside the thesis's numbers and warns about the undefined threshold rule."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import matplotlib.image as mpimg
import numpy as np
import polars as pl
import pytest

from graspstab.common.io import write_json, write_parquet
from graspstab.evaluation import studies
from graspstab.figures import common as fig_common
from graspstab.figures import entry as fig_entry
from graspstab.figures import sweep as fig_sweep
from graspstab.figures.artefacts import StudyArtefacts
from graspstab.figures.presentation import FIGURES, LEARNING_FIGURES
from graspstab.metrics.classification import (
    binary_metrics,
    per_object_metrics,
    select_threshold,
    threshold_grid,
)
from graspstab.report.learning import CAPTIONS, FIGURE_ANCHORS, learning_section
from graspstab.report.learning_tables import pct
from tests.study_layout import study_artefacts

FAMILIES = ("cnn", "gru", "lstm")
PARAMS = {"cnn": 176_833, "gru": 169_473, "lstm": 23_681}
OBJECTS = {"val": ("013_apple", "010_potted_meat_can"), "test": ("011_pear", "077_rubiks_cube")}
SEEDS = (42, 43)
WINDOWS = (0.01, 0.05, 0.2)


def _split(rng: np.random.Generator, n: int, unstable: float) -> tuple[np.ndarray, ...]:
    labels = (rng.random(n) < unstable).astype(np.int8)
    logits = rng.normal(2.5 * (2 * labels - 1), 1.5)
    probs = 1.0 / (1.0 + np.exp(-logits))
    objects = np.array([OBJECTS["val"][0]] * (n // 2) + [OBJECTS["val"][1]] * (n - n // 2))
    return labels, logits, probs, objects


def run_record(
    family: str, seed: int, val_unstable: float, test_unstable: float = 0.4, **extra: Any
) -> dict[str, Any]:
    """A metrics.json record as train_model writes it, from synthetic scores; with
    ``val_unstable`` 0 the validation split holds no unstable window (quick profile)."""
    k = int(extra.get("assignment_index", 0))
    rng = np.random.default_rng([seed, FAMILIES.index(family), int(1000 * val_unstable), k])
    rec: dict[str, Any] = {
        "family": family,
        "seed": seed,
        "parameters": PARAMS[family],
        "seconds_per_epoch": 1.0,
        "best_epoch": 3,
        "window_steps": 400,
    }
    data = {"val": _split(rng, 120, val_unstable), "test": _split(rng, 160, test_unstable)}
    data["test"] = (*data["test"][:3], np.repeat(OBJECTS["test"], 80))
    val_labels, _, val_probs, _ = data["val"]
    choice = select_threshold(val_probs, val_labels, threshold_grid())
    rec["threshold"] = {**vars(choice), "min_recall": 0.9}
    for split, (labels, logits, probs, objects) in data.items():
        rec[split] = binary_metrics(probs, labels, choice.threshold, logits=logits)
        rec[f"{split}_objects"] = per_object_metrics(probs, labels, objects, choice.threshold)
        rec[f"_{split}_frame"] = pl.DataFrame(
            {
                "sample_id": np.arange(len(labels), dtype=np.uint32),
                "object": objects,
                "split": [split] * len(labels),
                "label": labels,
                "logit": logits,
                "prob": probs,
            }
        )
    return {**rec, **extra}


def _write_record(path: Path, rec: dict[str, Any]) -> Path:
    frames = [rec.pop(k) for k in ("_val_frame", "_test_frame")]
    write_json(path / "metrics.json", rec)
    write_parquet(path / "predictions.parquet", pl.concat(frames))
    return path / "metrics.json"


def _baseline(results: Path) -> None:
    paths = [
        _write_record(results / "train" / "baseline" / f / f"seed{s}", run_record(f, s, 0.0))
        for f in FAMILIES
        for s in SEEDS
    ]
    studies.aggregate_baseline(paths, results / "studies" / "baseline")


def _latency(results: Path) -> Path:
    rows = [
        {
            "study": "baseline",
            "family": f,
            "window_s": 0.2,
            "window_steps": 400,
            "median_ms": 0.6 * (i + 1),
            "std_ms": 0.03,
            "mean_ms": 0.62 * (i + 1),
            "throughput_per_s": 1000 / (0.6 * (i + 1)),
        }
        for i, f in enumerate(FAMILIES)
    ]
    rows += [
        {
            "study": "sweep",
            "family": f,
            "window_s": w,
            "window_steps": int(w * 2000),
            "median_ms": 0.5 + i + w,
            "std_ms": 0.02,
            "mean_ms": 0.5 + i + w,
            "throughput_per_s": 1000 / (0.5 + i + w),
        }
        for i, f in enumerate(FAMILIES)
        for w in WINDOWS
    ]
    path = results / "studies" / "latency.parquet"
    write_parquet(path, pl.DataFrame(rows))
    return path


def _sweep(results: Path, latency: Path) -> None:
    paths = []
    for f in FAMILIES:
        for w in WINDOWS:
            for s in SEEDS:
                # one configuration (CNN, 0.05 s) has no unstable validation window
                val = 0.0 if (f, w) == ("cnn", 0.05) else 0.3 + 0.1 * w
                run = results / "train" / "sweep" / f / f"w{round(w * 1000)}ms" / f"seed{s}"
                paths.append(_write_record(run, run_record(f, s, val, window_s=w)))
    studies.aggregate_sweep(paths, latency, results / "studies" / "sweep")


def _splits(results: Path) -> None:
    assignments = [
        {
            "013_apple": "val",
            "010_potted_meat_can": "val",
            "011_pear": "test",
            "077_rubiks_cube": "test",
            "061_foam_brick": "train",
        },
        {
            "013_apple": "val",
            "011_pear": "val",
            "061_foam_brick": "test",
            "077_rubiks_cube": "test",
            "010_potted_meat_can": "train",
        },
        {
            "061_foam_brick": "val",
            "011_pear": "val",
            "013_apple": "test",
            "077_rubiks_cube": "test",
            "010_potted_meat_can": "train",
        },
    ]
    paths = []
    for k in range(len(assignments)):
        for s in SEEDS:
            run = results / "train" / "splits" / "lstm" / f"a{k}" / f"seed{s}"
            # the last assignment's test objects never slip: its test AUPRC is undefined
            test = 0.0 if k == len(assignments) - 1 else 0.4
            rec = run_record("lstm", s, 0.3, test, assignment_index=k)
            paths.append(_write_record(run, rec))
    studies.aggregate_splits(paths, assignments, results / "studies" / "splits")


def _proxy(results: Path) -> None:
    write_json(
        results / "studies" / "proxy.json",
        {
            "val": {"auprc": float("nan"), "auroc": float("nan"), "n": 120, "n_unstable": 0},
            "test": {"auprc": 0.91, "auroc": 0.88, "n": 160, "n_unstable": 64},
            "val_objects": {},
            "test_objects": {},
        },
    )


def _tuning(results: Path) -> None:
    for i, f in enumerate(FAMILIES):
        states = ["complete", "complete", "pruned", "complete", "fail"][: 3 + i]
        values = [0.80, 0.86, float("nan"), 0.84, float("nan")][: 3 + i]
        write_parquet(
            results / "tune" / f / "trials.parquet",
            pl.DataFrame(
                {
                    "number": list(range(len(states))),
                    "state": states,
                    "value": values,
                    "epochs_run": [5] * len(states),
                    "params": ["{'dropout': 0.1}"] * len(states),
                }
            ),
        )
        write_json(
            results / "tune" / f / "best.json",
            {
                "family": f,
                "spec": {"family": f, "dropout": 0.1, "learning_rate": 1e-3},
                "best_trial": 1,
                "best_value": 0.86,
                "objective": "auprc",
                "searched": ["dropout", "learning_rate"],
                "trials": {"complete": 2, "pruned": 1, "fail": 0, "running": 0, "waiting": 0},
            },
        )


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The synthetic results tree (baseline with undefined validation metrics)."""
    root = tmp_path_factory.mktemp("results")
    _baseline(root)
    _sweep(root, _latency(root))
    _splits(root)
    _proxy(root)
    _tuning(root)
    return root


@pytest.fixture(scope="module")
def written(results: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    return fig_entry.plot_learning(
        study_artefacts(results, first_seed=SEEDS[0]),
        tmp_path_factory.mktemp("figures"),
        60,
        SEEDS[0],
    )


def test_synthetic_tree_has_undefined_validation(results: Path) -> None:
    runs = pl.read_parquet(results / "studies" / "baseline" / "runs.parquet")
    val = runs.filter(pl.col("split") == "val")
    assert set(val["threshold_rule"]) == {"undefined"}
    assert val["auprc"].is_nan().all()


def test_every_figure_is_a_nontrivial_png(written: dict[str, Path]) -> None:
    assert set(written) == set(FIGURES)
    for name, path in written.items():
        assert path.name == FIGURES[name] and path.exists(), name
        img = mpimg.imread(path)
        assert img.ndim == 3 and 100 < img.shape[0] < 3000 and 200 < img.shape[1] < 3000, name
        assert np.std(img[..., :3]) > 0.02, f"{name} looks blank"


def test_missing_artefacts_give_placeholders(tmp_path: Path) -> None:
    for artefacts in (study_artefacts(tmp_path / "empty"), StudyArtefacts()):
        out = fig_entry.plot_learning(artefacts, tmp_path / "figs", 50, 42)
        for path in out.values():
            assert mpimg.imread(path).shape[0] > 50


def test_nan_bar_is_marked_undefined() -> None:
    fig, ax = fig_common.plt.subplots()
    stats = {"cnn": [(0.9, 0.01), (math.nan, math.nan)], "gru": [(math.nan, math.nan)] * 2}
    fig_common.grouped_bars(ax, ["AUROC", "AUPRC"], stats)
    texts = [t.get_text() for t in ax.texts]
    assert texts.count("undefined") == 3
    assert len(ax.patches) == 1  # only the defined bar is drawn
    fig_common.plt.close(fig)


def test_operating_points_with_no_defined_auprc(tmp_path: Path) -> None:
    """The quick profile's sweep: every validation AUPRC undefined, the latencies known."""
    points = pl.DataFrame(
        {
            "family": ["cnn", "gru", "lstm"],
            "window_s": [0.01, 0.02, 0.05],
            "val_auprc_mean": [None, None, None],
            "val_auprc_std": [None, None, None],
            "latency_ms": [0.7, 3.3, 1.2],
            "latency_std_ms": [0.02, 0.03, 0.02],
            "total_latency_ms": [10.7, 23.3, 51.2],
        },
        schema_overrides={"val_auprc_mean": pl.Float64, "val_auprc_std": pl.Float64},
    )
    overview = {
        "choice": {
            "defined": False,
            "reason": "no configuration has a defined validation AUPRC",
            "rule": "...",
        },
        "best_windows": [],
    }
    path = fig_sweep.plot_operating_points(points, overview, tmp_path / "op.png", 60)
    img = mpimg.imread(path)
    assert 100 < img.shape[0] < 3000 and 200 < img.shape[1] < 3000


def test_section_embeds_figures_references_and_warning(
    results: Path, written: dict[str, Path]
) -> None:
    html = learning_section(study_artefacts(results), written, {"profile_name": "quick"})
    assert html.count('src="data:image/png;base64,') == len(FIGURES)
    for ref in (
        "178,753",
        "171,777",
        "25,217",
        "98.43 ± 0.05 %",
        "99.25 ± 0.01 %",
        "1723 ± 165",
        "24.46 %",
        "0.625 ± 0.032",
        "97.14 ± 2.49 %",
        "96.27 %",
        "98.41 %",
    ):
        assert ref in html, ref
    assert "Warning: undefined validation metrics" in html
    assert "held no unstable window" in html
    text = re.sub(r'src="data:image/png;base64,[^"]*"', "", html)
    assert "undefined" in text and not re.search(r"\bnan\b", text, re.IGNORECASE)
    assert "lowest total decision latency" in html  # the sweep's rule text


def test_section_without_results_says_so(tmp_path: Path) -> None:
    for artefacts in (study_artefacts(tmp_path), StudyArtefacts()):
        html = learning_section(artefacts, {}, {})
        assert "Not produced in this run" in html and "<img" not in html


def test_pct_formats_nan_as_undefined() -> None:
    assert pct(float("nan")) == "undefined"
    assert pct(0.9843, 0.0005) == "98.43 ± 0.05 %"
    assert pct(0.9, float("nan")) == "90.00 ± undefined %"


# --------------------------------------------------------- one figure list, declared inputs


def test_figure_names_are_one_list_and_match_the_written_files(
    written: dict[str, Path], tmp_path: Path
) -> None:
    """LEARNING_FIGURES is the figures', the report's and rule plot_learning's list: the files
    plot_learning writes are exactly its names (no stray temporary file of an atomic write)."""
    assert fig_entry.FIGURES is FIGURES and list(FIGURES) == list(LEARNING_FIGURES)
    assert set(FIGURE_ANCHORS) == set(CAPTIONS) == set(LEARNING_FIGURES)
    out_dir = {p.parent for p in written.values()}
    assert len(out_dir) == 1
    assert sorted(p.name for p in out_dir.pop().iterdir()) == sorted(FIGURES.values())
    assert {n: p.name for n, p in written.items()} == FIGURES
    train = (Path(__file__).resolve().parents[1] / "workflow" / "rules" / "train.smk").read_text()
    assert "from graspstab.figures.presentation import FIGURES as LEARNING_FIGURE_FILES" in train
    assert "LEARNING_FIGURES = [" not in train  # no second list in the workflow
    # named outputs, as the rule gives them: every name, and no other
    named = {n: tmp_path / "named" / f"x_{n}.png" for n in LEARNING_FIGURES}
    got = fig_entry.plot_learning(StudyArtefacts(), named, 40, 42)
    assert got == named and all(p.exists() for p in named.values())
    with pytest.raises(ValueError, match="writes exactly"):
        fig_entry.plot_learning(StudyArtefacts(), {"benchmark": tmp_path / "b.png"}, 40, 42)


def _record_reads(monkeypatch: pytest.MonkeyPatch, roots: list[Path]) -> list[Path]:
    """Every Parquet and text file read below ``roots`` from now on."""
    reads: list[Path] = []
    read_parquet, read_text = pl.read_parquet, Path.read_text

    def note(path: Any) -> None:
        p = Path(path).resolve()
        if any(p.is_relative_to(r.resolve()) for r in roots):
            reads.append(p)

    def parquet(source: Any, *args: Any, **kwargs: Any) -> pl.DataFrame:
        note(source)
        return read_parquet(source, *args, **kwargs)

    def text(self: Path, *args: Any, **kwargs: Any) -> str:
        note(self)
        return read_text(self, *args, **kwargs)

    monkeypatch.setattr(pl, "read_parquet", parquet)
    monkeypatch.setattr(Path, "read_text", text)
    return reads


def _given(a: StudyArtefacts) -> set[Path]:
    paths = [getattr(a, f) for f in a.__dataclass_fields__]
    flat = [p for v in paths for p in (v.values() if isinstance(v, dict) else [v])]
    return {Path(p).resolve() for p in flat if p is not None}


def test_readers_read_only_the_paths_they_are_given(
    results: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """plot_learning and the report's learning section read the given paths and nothing else:
    artefacts present in the tree but not given are not read, and a corrupt results/ tree in
    the working directory (a decoy for any walk of 'results') is never touched."""
    decoy = tmp_path / "results"
    for rel in ("studies/latency.parquet", "studies/baseline/runs.parquet", "tune/gru/best.json"):
        (decoy / rel).parent.mkdir(parents=True, exist_ok=True)
        (decoy / rel).write_text("corrupt")
    monkeypatch.chdir(tmp_path)
    full = study_artefacts(results, first_seed=SEEDS[0])
    given = StudyArtefacts(
        **{
            **{f: getattr(full, f) for f in full.__dataclass_fields__},
            "latency": None,  # on disk in the tree, not given
            "trials": {f: p for f, p in full.trials.items() if f != "gru"},
            "best": {f: p for f, p in full.best.items() if f != "gru"},
        }
    )
    reads = _record_reads(monkeypatch, [results, tmp_path])
    out = fig_entry.plot_learning(given, tmp_path / "figs", 40, SEEDS[0])
    html = learning_section(given, out, {"profile_name": "quick"})
    assert reads and set(reads) <= _given(given), sorted(set(reads) - _given(given))
    assert (results / "studies" / "latency.parquet").exists()
    assert "Not produced in this run: the artefact was not given" in html  # the latency table
    assert not any(p.is_relative_to(decoy.resolve()) for p in reads)


def test_artefacts_from_named_inputs() -> None:
    """A rule's named inputs become StudyArtefacts; only names behind the prefix are taken."""
    named = {
        "study_baseline_runs": "a/runs.parquet",
        "study_best_gru": ["t/gru/best.json"],
        "study_predictions_cnn": "p/cnn.parquet",
        "meta": ["x.json", "y.json"],  # another input of the rule, left alone
    }
    got = StudyArtefacts.from_inputs(named, prefix="study_")
    assert got.baseline_runs == Path("a/runs.parquet") and got.latency is None
    assert got.best == {"gru": Path("t/gru/best.json")}
    assert got.predictions == {"cnn": Path("p/cnn.parquet")} and got.trials == {}
    with pytest.raises(ValueError, match="no study artefact"):
        StudyArtefacts.from_inputs({"baseline_run": "typo.parquet"})
    with pytest.raises(ValueError, match="one file"):
        StudyArtefacts.from_inputs({"latency": ["a", "b"]})
