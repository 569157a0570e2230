"""The sensor-robustness study on synthetic replays: segments end at the dataset's windows, the
clean condition reproduces the clean evaluation, and each condition reaches every scorer."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import polars as pl
import pytest
import torch
import yaml
from conftest import CONFIG_DIR
from synthetic_replays import labelled_replays

from graspstab.evaluation.proxy import friction_ratio, proxy_metrics
from graspstab.evaluation.robustness import conditions, evaluate_robustness
from graspstab.labels.dataset import load_windows
from graspstab.labels.trace_windows import trace_map
from graspstab.learning.data import load_window_data
from graspstab.learning.models import build_model
from graspstab.metrics.classification import binary_metrics
from graspstab.replay.traces import trace_key
from graspstab.sensing.segments import SegmentError, window_segments

LABELS = yaml.safe_load((CONFIG_DIR / "labels" / "default.yaml").read_text())
SENSING = yaml.safe_load((CONFIG_DIR / "sensing" / "default.yaml").read_text())
DT = 0.0005
T = 6000  # 3 s


def _trace(slip_at: int, rng: np.random.Generator) -> dict:
    """Held still, then slipping at 5 mm/s from ``slip_at``; shear rises towards the slip."""
    vel = np.zeros((T, 3), np.float32)
    vel[slip_at:, 2] = -0.005
    normal = (2 + rng.random((T, 5))).astype(np.float32)
    ramp = np.clip(np.arange(T) / slip_at, 0, 1.5)[:, None]
    shear = (normal * (0.1 + 0.5 * ramp) + 0.05 * rng.random((T, 5))).astype(np.float32)
    return {"position": np.zeros((T, 3), np.float32), "velocity": vel,
            "min_distance": np.full(T, -0.001, np.float32), "normal": normal,
            "shear": shear}  # fmt: skip


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> tuple[Path, list[str], list[tuple[str, int]]]:
    rng = np.random.default_rng(0)
    ds, traces = labelled_replays(
        tmp_path_factory.mktemp("sensing"), (("a", 0, (0, 1)), ("b", 1, (3,)), ("c", 0, (5, 6))),
        lambda g: _trace(2500 + 500 * g, rng), LABELS, {"a": "train", "b": "val", "c": "test"},
        DT,
    )  # fmt: skip
    return ds, list(traces.values()), list(traces)


def test_segments_end_at_the_dataset_windows(dataset) -> None:
    """The last W frames of every segment are the dataset's window; the context precedes it."""
    ds, paths, keys = dataset
    data = load_window_data(ds)
    windows = load_windows(ds)
    seg = window_segments(data.index, trace_map(paths, keys), data.window_steps, 37)
    assert seg.shape == (len(windows), 37 + data.window_steps, 5, 2)
    np.testing.assert_array_equal(seg[:, 37:], windows)
    # the context is the trace's frames before the window (the windows start after settling)
    row = data.index.filter(pl.col("start") >= 37).row(0, named=True)
    with np.load(dict(zip(keys, paths, strict=True))[(row["object"], row["shard"])]) as npz:
        normal = npz[trace_key(row["grasp_id"], "normal")]
    np.testing.assert_array_equal(seg[row["sample_id"], :, :, 0],
                                  normal[row["start"] - 37 : row["end"]])  # fmt: skip
    with pytest.raises(SegmentError, match="no trace file"):
        window_segments(data.index, {}, data.window_steps, 0)


def test_clean_condition_reproduces_the_clean_evaluation(dataset, tmp_path: Path) -> None:
    """Clean point = the model and proxy scored on the dataset's own windows; every condition
    reaches every scorer; the same seed gives the same table."""
    ds, paths, keys = dataset
    data = load_window_data(ds)
    torch.manual_seed(0)
    spec = {"family": "cnn", "base_channels": 4, "kernel_sizes": [3, 3], "dropout": 0.0}
    model = build_model(spec).eval()
    ckpt = tmp_path / "model.pt"
    torch.save({"state_dict": model.state_dict(), "model": spec,
                "window_steps": data.window_steps, "mean": data.mean.tolist(),
                "std": data.std.tolist()}, ckpt)  # fmt: skip
    sensing = {**SENSING, "curves": {"noise": [0.5], "rate": [60], "drop": [0.5]},
               "presets": {"slow": {"rate_hz": 100, "delay_s": 0.01}}}  # fmt: skip
    args = (ds, paths, keys, [ckpt], [{"family": "cnn", "seed": 7}], sensing, DT, 0)
    table = evaluate_robustness(*args, tmp_path / "r.parquet", tmp_path / "r.json")
    assert table.height == len(conditions(sensing)) * 2
    rows = data.rows("test")
    y = data.labels(rows)
    with torch.inference_mode():
        logits = model(data.batch(rows)).double().numpy()
    expect = binary_metrics(1 / (1 + np.exp(-logits)), y, 0.5, logits=logits)["auprc"]
    clean = table.filter(pl.col("kind") == "clean")
    got = dict(zip(clean["family"], clean["auprc"], strict=True))
    assert got["cnn"] == pytest.approx(expect, abs=1e-6)
    assert got["proxy"] == pytest.approx(
        proxy_metrics(friction_ratio(load_windows(ds)[rows]), y)["auprc"], abs=1e-9
    )
    assert set(table["corruption"]) == {"none", "noise", "rate", "drop", "slow"}
    assert table.filter(pl.col("family") == "cnn")["seed"].unique().to_list() == [7]
    summary = json.loads((tmp_path / "r.json").read_text())
    assert summary["n"] == len(rows) and summary["chance"] == pytest.approx(y.mean())
    again = evaluate_robustness(*args, tmp_path / "s.parquet", tmp_path / "s.json")
    assert again.equals(table)
    # a strong noise changes the proxy's score (it reads one frame): the condition was applied
    noisy = table.filter((pl.col("corruption") == "noise") & (pl.col("family") == "proxy"))
    assert noisy["auprc"][0] != got["proxy"]


def test_robustness_figure_draws_curves_and_says_when_undefined(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A defined table: each panel draws the scorers' curves and the chance line. An undefined
    AUPRC (NaN, JSON null in the study's files): each panel says "AUPRC undefined" and draws no
    curve, chance line or legend; the report's table reads null as undefined, never a number."""
    from graspstab.figures import robustness
    from graspstab.figures.presentation import UNDEFINED
    from graspstab.report.sensing import condition_table

    figures = {}
    save = robustness.save

    def keep(fig, path, dpi):  # the figure as drawn, before it is written and closed
        figures[Path(path).name] = [(ax.get_title(), len(ax.containers),
                                     [line.get_linestyle() for line in ax.lines],
                                     [t.get_text() for t in ax.texts], ax.get_legend())
                                    for ax in fig.axes if ax.get_visible()]  # fmt: skip
        return save(fig, path, dpi)

    monkeypatch.setattr(robustness, "save", keep)
    plot_robustness = robustness.plot_robustness

    rows = [
        {
            "kind": "clean",
            "corruption": "none",
            "strength": 0.0,
            "family": f,
            "seed": 1,
            "training": t,
            "auprc": 0.9,
        }
        for f, t in (("cnn", "clean"), ("proxy", "none"))
    ]
    rows += [
        {
            "kind": "curve",
            "corruption": c,
            "strength": v,
            "family": "cnn",
            "seed": 1,
            "training": "clean",
            "auprc": 0.8,
        }
        for c, v in (("rate", 60.0), ("noise", 0.5))
    ]
    table = pl.DataFrame(rows)
    assert plot_robustness(table, 0.5, tmp_path / "a.png").stat().st_size > 1000
    # one panel per curve, each with the CNN's and the proxy's points (the clean point at the
    # curve's "off" end) and the dotted chance line
    assert sorted(p[0] for p in figures["a.png"]) == ["noise", "rate"]
    for _, errorbars, styles, texts, _ in figures["a.png"]:
        assert errorbars == 2 and ":" in styles and "AUPRC undefined" not in texts
    assert figures["a.png"][0][4] is not None  # the legend names them
    undefined = table.with_columns(pl.lit(float("nan")).alias("auprc"))
    png = plot_robustness(undefined, float("nan"), tmp_path / "b.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p[0] for p in figures["b.png"]) == ["noise", "rate"]
    for _, errorbars, styles, texts, legend in figures["b.png"]:
        assert (errorbars, styles, texts, legend) == (0, [], ["AUPRC undefined"], None)
    # the summary's undefined mean arrives as JSON null: the table says so
    summary = [{"kind": r["kind"], "corruption": r["corruption"], "strength": r["strength"],
                "family": r["family"], "training": r["training"], "auprc_mean": None,
                "auprc_std": None, "runs": 1} for r in rows]  # fmt: skip
    summary = json.loads(json.dumps(summary))
    _, table_rows = condition_table(summary, ("clean", "curve"))
    assert [r[2:] for r in table_rows] == [[UNDEFINED, UNDEFINED]] * 3


def test_augmentation_passes_training_windows_through_drawn_sensors(dataset) -> None:
    """A pure delay sensor gives the trace d frames earlier, clean_share keeps that share clean,
    and only training rows are accepted."""
    from graspstab.learning.augmentation import SensorAugmentation
    from graspstab.sensing.sensor_model import SensorModel

    ds, paths, keys = dataset
    data = load_window_data(ds)
    rows = data.rows("train")
    delay = SensorModel(delay_s=10 * DT)
    aug = SensorAugmentation(data, [delay], trace_map(paths, keys), DT, seed=0)
    out = aug(rows)
    seg = window_segments(data.index[rows], trace_map(paths, keys), data.window_steps, 10)
    np.testing.assert_array_equal(out, seg[:, : data.window_steps])  # 10 frames earlier
    half = SensorAugmentation(data, [delay], trace_map(paths, keys), DT, seed=0, clean_share=0.5)
    clean = (half(rows) == load_windows(ds)[rows]).all(axis=(1, 2, 3))
    assert 0.3 < clean.mean() < 0.7
    with pytest.raises(ValueError, match="training rows only"):
        aug(data.rows("test"))
    data.augment = aug
    np.testing.assert_allclose(data.train_batch(rows[:3]).numpy(),
                               (out[:3] - data.mean) / data.std, rtol=1e-5, atol=1e-5)  # fmt: skip


def test_train_model_with_augmentation_records_it(dataset, tmp_path: Path) -> None:
    """An augmented training runs end to end and stores the sensing settings with its params."""
    from graspstab.evaluation.tested_run import train_and_test

    ds, paths, keys = dataset
    spec = {"family": "cnn", "base_channels": 4, "kernel_sizes": [3], "dropout": 0.0,
            "learning_rate": 1e-3}  # fmt: skip
    train = yaml.safe_load((CONFIG_DIR / "train" / "default.yaml").read_text())
    train.update(max_epochs=1, patience=1)
    sensing = {**SENSING, "curves": {"noise": [0.5]}, "presets": {}}
    record = train_and_test(ds, spec, train, 3, tmp_path / "run", augment={
        "sensing": sensing, "trace_paths": paths, "trace_keys": keys, "dt": DT})  # fmt: skip
    assert record["params"]["augment"]["sensing"]["curves"] == {"noise": [0.5]}
    assert (tmp_path / "run" / "model.pt").exists()


def test_augmentation_modes_draw_from_the_mixture_or_one_curve() -> None:
    """The mixture draws every curve strength and preset; a corruption's mode its curve only;
    a mode naming no curve is refused with the fix; labels tell the modes apart."""
    from graspstab.learning.augmentation import augmentation_sensors
    from graspstab.sensing.conditions import training_label

    curves = sum(len(v) for v in SENSING["curves"].values())
    assert len(augmentation_sensors(SENSING)) == curves + len(SENSING["presets"])
    rate = augmentation_sensors(SENSING, "rate")
    assert [s.rate_hz for s in rate] == [float(v) for v in SENSING["curves"]["rate"]]
    assert {s.noise for s in rate} == {0.0}  # nothing but the rate
    with pytest.raises(ValueError, match="names no curve"):
        augmentation_sensors({**SENSING, "curves": {"noise": [0.1]}}, "drift")
    assert training_label("mixture") == "augmented"
    assert training_label("drift") == "augmented:drift"


def _summary_rows() -> list[dict]:
    rows = []
    for kind, corruption, strength in (
        ("clean", "none", 0.0),
        ("curve", "noise", 0.5),
        ("curve", "rate", 60.0),
        ("preset", "vision_60hz", None),
    ):
        for family, training, auprc in (
            ("lstm", "clean", 0.9),
            ("lstm", "augmented", 0.8),
            ("lstm", "augmented:noise", 0.7),
            ("lstm", "augmented:rate", 0.6),
            ("proxy", "none", 0.5),
        ):
            rows.append({"kind": kind, "corruption": corruption,
                         "strength": float("nan") if strength is None else strength,
                         "family": family, "training": training, "auprc_mean": auprc,
                         "auprc_std": 0.0, "runs": 1})  # fmt: skip
    return rows


def test_condition_table_puts_each_corruption_model_on_its_own_rows() -> None:
    from graspstab.report.sensing import condition_table

    headers, rows = condition_table(_summary_rows(), ("clean", "curve"))
    assert headers == ["condition", "strength", "LSTM", "LSTM (through sensors)",
                       "LSTM (through this corruption)", "proxy"]  # fmt: skip
    by = {r[0]: r for r in rows}
    assert by["noise"][2:] == ["90.0", "80.0", "70.0", "50.0"]
    assert by["rate"][2:] == ["90.0", "80.0", "60.0", "50.0"]
    assert by["clean (simulator)"][4] == "n/a"  # no single "own" model on the clean row
    _, only = condition_table(_summary_rows(), ("clean", "curve", "preset"), ("rate",))
    assert [r[0] for r in only] == ["clean (simulator)", "rate", "vision_60hz"]


def test_robustness_figure_draws_a_corruption_model_in_its_panel_only(tmp_path: Path) -> None:
    from graspstab.figures import robustness

    table = pl.DataFrame([{**{k: r[k] for k in ("kind", "corruption", "strength", "family",
                                                 "training")}, "seed": 1, "auprc": r["auprc_mean"]}
                          for r in _summary_rows() if r["kind"] != "preset"])  # fmt: skip
    drawn = {}
    original = robustness.plt.Axes.errorbar

    def spy(ax, *args, **kwargs):
        drawn.setdefault(ax.get_title() or id(ax), []).append(kwargs["label"])
        return original(ax, *args, **kwargs)

    robustness.plt.Axes.errorbar = spy
    try:
        robustness.plot_robustness(table, 0.5, tmp_path / "c.png")
    finally:
        robustness.plt.Axes.errorbar = original
    labels = [sorted(v) for v in drawn.values()]
    assert sorted(["LSTM", "LSTM (through sensors)", "LSTM (this corruption)", "proxy"]) in labels
    assert sum(v.count("LSTM (this corruption)") for v in labels) == 2  # one per panel


def test_audit_table_lists_the_leakage_control_last(tmp_path: Path) -> None:
    """Whatever order the aggregate holds, the rows follow the input sets' order (forces first,
    object state last, as the section's text says), with each set's width and parameters."""
    from graspstab.report.sensing import audit_section

    sets = {"object_state": 16, "forces": 10, "tangential": 15, "normal": 5}
    summary = [{"input_set": s, "family": "lstm", "split": "test", "auprc_mean": 0.9,
                "auprc_std": 0.0, "auprc_n": 1} for s in sets]  # fmt: skip
    shapes = [{"input_set": s, "family": "lstm", "inputs": w, "parameters": 1000 + w}
              for s, w in sets.items()]  # fmt: skip
    path = tmp_path / "summary.json"
    path.write_text(json.dumps({"summary": summary, "shapes": shapes}))
    html = audit_section({"summary": str(path)})
    at = [
        html.index(label)
        for label in (
            "5 × normal, shear",
            "normal only",
            "two fingertip-frame components",
            "velocity (leakage control)",
        )
    ]
    assert at == sorted(at)
    assert "1,016" in html and "1,015" in html


def test_still_now_condition_table_reads_the_still_columns() -> None:
    """The sensing section's still-now table reads each condition's still-now mean (null where no
    still-now window is unstable: undefined, never 0), beside the unchanged all-window table."""
    from graspstab.figures.presentation import UNDEFINED
    from graspstab.report.sensing import condition_table

    summary = [{"kind": "clean", "corruption": "none", "strength": 0.0, "family": f,
                "training": t, "auprc_mean": 0.9, "auprc_std": None, "runs": 1,
                "still_auprc_mean": s} for f, t, s in (("cnn", "clean", 0.4),
                                                        ("proxy", "none", None))]  # fmt: skip
    _, rows = condition_table(summary, ("clean",), metric="still_auprc")
    assert rows == [["clean (simulator)", "", "40.0", UNDEFINED]]
    _, rows = condition_table(summary, ("clean",))
    assert rows == [["clean (simulator)", "", "90.0", "90.0"]]
