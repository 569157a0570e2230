"""End to end: the whole DAG for three objects (train, val, test) in a temporary directory."""

from __future__ import annotations

import base64
import json
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from tests.conftest import REPO
from tests.toy_workflow import (
    OBJECT,
    OBJECTS,
    TOY_CREEP_FREE,
    TOY_REPLAY,
    TOY_SYNTHESIS,
    copy_run,
    listed_jobs,
)
from tests.toy_workflow import (
    snakemake_run as _snakemake,
)


def _dry_jobs(workdir: Path, config: list[str], env: dict[str, str], *extra: str) -> list[dict]:
    """The jobs a dry run of the report would run."""
    proc = _snakemake(workdir, "results/report.html", "--dry-run", *config, *extra, env=env)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return listed_jobs(proc.stdout)


def _with(config: list[str], old: str, new: str) -> list[str]:
    """The config list with one --config item replaced (--config keys do not merge)."""
    assert old in config
    return [new if item == old else item for item in config]


@pytest.mark.workflow
def test_one_object_end_to_end(run):
    workdir, _, _ = run
    obj = workdir / "results" / "objects" / OBJECT
    for name in (
        "mesh.obj",
        "convex_parts.npz",
        "object.xml",
        "sdf.npz",
        "hull_points.npy",
        "meta.json",
    ):
        assert (obj / name).stat().st_size > 0, name
    meta = json.loads((obj / "meta.json").read_text())
    assert meta["mass"] == pytest.approx(0.028)
    assert meta["watertight_after"] is True
    assert (workdir / "resources" / "ycb" / OBJECT / "textured.obj").is_file()
    hand = workdir / "results" / "hand"
    for name in ("hand.xml", "hand.json", "capsules.json", "contact_candidates.npz"):
        assert (hand / name).is_file(), name
    figures = ("objects.png", "hand_candidates.png", "hand_capsules.png", "pregrasp.png")
    for name in (*figures, "grasp_gallery.png", "energy_histograms.png"):
        assert (workdir / "results" / "figures" / name).stat().st_size > 1000
    assert (workdir / "results" / "logs" / "preprocess_object" / f"{OBJECT}.log").is_file()
    bench = workdir / "results" / "benchmarks" / "preprocess_object" / f"{OBJECT}.tsv"
    assert bench.is_file()


@pytest.mark.workflow
def test_grasp_shards_and_summary(run):
    import polars as pl

    workdir, _, _ = run
    grasps = workdir / "results" / "grasps" / OBJECT
    tables = [pl.read_parquet(grasps / f"shard_{k}.parquet") for k in range(2)]
    assert [t.height for t in tables] == [4, 4]
    ids = pl.concat(tables)["grasp_id"].to_list()
    assert sorted(ids) == list(range(8))  # unique across shards
    assert (pl.concat(tables)["energy"] <= pl.concat(tables)["energy_start"]).all()
    summary = json.loads((grasps / "summary.json").read_text())
    assert summary["grasps"] == 8 and summary["shards"] == 2


@pytest.mark.workflow
def test_replay_traces_and_summary(run):
    import numpy as np
    import polars as pl

    from graspstab.replay.traces import trace_key

    workdir, _, _ = run
    replay = workdir / "results" / "replay" / OBJECT
    for shard in range(2):
        table = pl.read_parquet(replay / f"replays_{shard}.parquet")
        grasps = pl.read_parquet(workdir / "results" / "grasps" / OBJECT / f"shard_{shard}.parquet")
        assert table["grasp_id"].to_list() == grasps["grasp_id"].to_list()
        assert set(table["stop_reason"]) <= {"completed", "contact_lost", "diverged"}
        assert (table["steps"] <= 2000).all()
        with np.load(replay / f"traces_{shard}.npz") as traces:
            for row in table.iter_rows(named=True):
                normal = traces[trace_key(row["grasp_id"], "normal")]
                assert normal.shape == (row["steps"], 5) and normal.dtype == np.float32
                pos = traces[trace_key(row["grasp_id"], "position")]
                np.testing.assert_allclose(pos[0], 0.0, atol=1e-5)  # object frame, at rest


@pytest.mark.workflow
def test_creep_free_benchmark_replays_the_same_grasps_under_the_ramp(run):
    """The creep-free benchmark (creep_free.enabled): the main run's grasps replayed under the
    strict model with the load ramp, recorded, labelled, trained and set beside the main run."""
    import numpy as np
    import polars as pl

    from graspstab.common.io import read_parquet_metadata
    from graspstab.replay.traces import trace_key

    workdir, _, _ = run
    cf = workdir / "results" / "creep_free"
    meta = read_parquet_metadata(cf / "replay" / OBJECT / "replays_0.parquet")
    assert meta["protocol"] == "ramp" and meta["contact_model"] == "strict"
    assert meta["squeeze_rad"] == 0.0
    main = pl.read_parquet(workdir / "results" / "replay" / OBJECT / "replays_0.parquet")
    table = pl.read_parquet(cf / "replay" / OBJECT / "replays_0.parquet")
    assert table["grasp_id"].to_list() == main["grasp_id"].to_list()  # the same grasps
    assert (table["ramp_peak_load_mg"] <= 5.0 + 1e-6).all()
    meta_object = json.loads((workdir / "results" / "objects" / OBJECT / "meta.json").read_text())
    weight = float(meta_object["mass"]) * 9.81
    with np.load(cf / "replay" / OBJECT / "traces_0.npz") as traces:
        for row in table.iter_rows(named=True):
            load = np.linalg.norm(traces[trace_key(row["grasp_id"], "load")], axis=1)
            t = np.arange(len(load)) * 0.0005
            # the linear path: F(t) = m g k (t - t0), capped at the ceiling
            np.testing.assert_allclose(load, np.clip(weight * 10.0 * (t - 0.3), 0, 5 * weight),
                                       rtol=1e-4, atol=1e-6)  # fmt: skip
    for name in ("baseline/index.parquet", "sweep/w10ms/index.parquet"):
        assert (cf / "datasets" / name).is_file()
    runs = pl.read_parquet(cf / "studies" / "baseline" / "runs.parquet")
    assert set(runs["family"]) == {"cnn", "gru", "lstm"}
    assert json.loads((cf / "studies" / "proxy.json").read_text())["test"]["n"] > 0
    html = (workdir / "results" / "report.html").read_text()
    section = html[html.index('id="protocols"') : html.index('id="provenance"')]
    assert "load ramp (strict contact model)" in section and "gravity (reference" in section
    assert "Learned models beat the friction-ratio proxy" in section
    assert "no creep-free" not in section


@pytest.mark.workflow
def test_ramp_parameter_reruns_the_creep_free_benchmark_only(run):
    workdir, env, config = run
    changed = _with(config, TOY_REPLAY, TOY_REPLAY.replace("rate: 10.0", "rate: 8.0"))
    rules = {j["rule"] for j in _dry_jobs(workdir, changed, env)}
    assert {"replay_grasps_creep_free", "label_windows_creep_free", "train_model_creep_free",
            "report"} <= rules  # fmt: skip
    assert not rules & {"replay_grasps", "label_windows", "train_model", "anneal_grasps"}


@pytest.mark.workflow
def test_datasets_baseline_and_sweep(run):
    import numpy as np
    import polars as pl

    workdir, _, _ = run
    data = workdir / "results" / "datasets"
    base = pl.read_parquet(data / "baseline" / "index.parquet")
    assert np.load(data / "baseline" / "windows.npy", mmap_mode="r").shape[1:] == (400, 5, 2)
    assert set(base["split"].unique()) == {"train", "val", "test"}
    splits = {"061_foam_brick": "train", "014_lemon": "val", "077_rubiks_cube": "test"}
    assert all(splits[o] == s for o, s in base.select("object", "split").unique().iter_rows())
    ref = pl.read_parquet(data / "sweep" / "reference" / "index.parquet")
    for ms in (10, 20):
        sweep = pl.read_parquet(data / "sweep" / f"w{ms}ms" / "index.parquet")
        windows = np.load(data / "sweep" / f"w{ms}ms" / "windows.npy", mmap_mode="r")
        assert windows.shape == (ref.height, ms * 2, 5, 2)
        for col in ("sample_id", "end", "label", "split"):
            assert sweep[col].to_list() == ref[col].to_list()


@pytest.mark.workflow
def test_labelling_parameter_reruns_labelling_only(run):
    workdir, env, config = run
    changed = [*config, "labels={v_slip: 0.002}"]
    proc = _snakemake(workdir, "results/report.html", "--dry-run", *changed, env=env)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    jobs = set(re.findall(r"^(\w+)\s+\d+$", proc.stdout, flags=re.M)) - {"total"}
    assert {"label_windows", "label_sweep_reference", "trim_sweep_window", "report"} <= jobs
    assert not jobs & {"anneal_grasps", "replay_grasps", "preprocess_object", "build_hand"}


@pytest.mark.workflow
def test_report_is_self_contained(run):
    workdir, _, _ = run
    html = (workdir / "results" / "report.html").read_text()
    assert OBJECT in html and "Provenance" in html and "Grasp synthesis" in html
    assert "Grasp replay" in html and "Window datasets" in html
    assert "Learning and evaluation" in html
    # no external requests: no http(s) sources or stylesheets
    assert not re.search(r'(src|href)="https?://', html)
    images = re.findall(r'src="data:image/png;base64,([^"]+)"', html)
    # objects, hand x2, pre-grasp, gallery, histograms, replay, speeds, window + 11 learning
    # figures + the rule graph + the two speed figures of "Two protocols side by side" + the
    # monitor's two figures under each protocol + the sensor-robustness curves + the failure
    # anatomy under each protocol
    assert len(images) == 9 + 11 + 1 + 2 + 2 + 2 + 1 + 2
    for data in images:
        assert base64.b64decode(data)[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.workflow
def test_second_run_does_nothing(run):
    workdir, env, config = run
    proc = _snakemake(workdir, "results/report.html", "--dry-run", *config, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "Nothing to be done" in proc.stdout + proc.stderr


# The documented alternatives of the replay protocol (README "Replay protocols") against the quick
# profile's choices: the strict contact model, no squeeze and the settle reading `both` in one
# run through labelling; eq. 16's energy in a second one. Replays of 4 s: the
# reading `both` needs the distance check, whose reference median lies at 2.8-3 s (3.3.1), so 1 s
# replays would all fall back to 3 s and give no window.
ALT_REPLAY = "replay={steps: 8000, chunk_steps: 1000, squeeze: {angle: 0.0}}"
ALTERNATIVES = ["contact=strict", "labels={settle: {require: both}}"]


def _object_replays(workdir: Path) -> list[str]:
    """OBJECT's replay outputs (tables and traces) in ``workdir``, as Snakemake targets."""
    return sorted(str(p.relative_to(workdir))
                  for p in (workdir / "results" / "replay" / OBJECT).glob("*_*.*"))  # fmt: skip


@pytest.mark.workflow
def test_alternative_protocol_options_run_through_labelling(run, tmp_path):
    """The strict model, no squeeze and the `both` reading run for real through replay and
    labelling, in a copy of the toy run, and each shows in what it made: the replays' metadata
    and the settle rules' speeds. Snakemake reruns what the options change and no more: they
    leave the hand, the objects and the grasps alone. The rest of the way to the report is
    checked as a dry run (the learning stages read windows, whatever made them); the report's
    rendering of these options is tests/test_report.py's, on a synthetic results tree."""
    import polars as pl

    from graspstab.common.io import read_parquet_metadata

    workdir, env, config = run
    # without the toy run's creep-free, sensing and audit outputs: this run has none of them
    alt = copy_run(workdir, tmp_path / "alt", "creep_free", "sensing", "inputs")
    alt_config = _with(_with(config, TOY_REPLAY, ALT_REPLAY), TOY_CREEP_FREE,
                       "creep_free={enabled: false}")  # fmt: skip
    alt_config += ["sensing={robustness: false}", "audit={enabled: false}"]
    labelled = ["results/datasets/speeds.json", "results/datasets/baseline/index.parquet"]
    proc = _snakemake(alt, *labelled, *alt_config, *ALTERNATIVES, env=env)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-4000:]
    rules = {j["rule"] for j in listed_jobs(proc.stdout + proc.stderr)}
    assert {"replay_grasps", "label_windows"} <= rules
    upstream = {"fetch_ycb_object", "build_hand", "preprocess_object", "anneal_grasps"}
    assert not rules & upstream, rules & upstream
    meta = read_parquet_metadata(alt / "results" / "replay" / OBJECT / "replays_0.parquet")
    assert meta["contact_model"] == "strict" and meta["squeeze_rad"] == 0.0
    assert meta["mujoco_version"] and meta["provenance"]["params"]["contact"]["impratio"] == 10.0
    speeds = json.loads((alt / "results" / "datasets" / "speeds.json").read_text())
    assert speeds["contact_model"] == "strict"
    assert speeds["box_creep"]["speed"] < 0.1 * speeds["v_slip"]  # strict: creep-free
    index = pl.read_parquet(alt / "results" / "datasets" / "baseline" / "index.parquet")
    assert set(index["split"]) == {"train", "val", "test"}
    # from there to the report: every learning stage and the report, nothing upstream again,
    # none of the disabled studies
    rest = {j["rule"] for j in _dry_jobs(alt, [*alt_config, *ALTERNATIVES], env)}
    assert {"train_model", "tune_model", "train_sweep_model", "export_monitor",
            "evaluate_monitor", "report"} <= rest  # fmt: skip
    assert not rest & (upstream | {"replay_grasps", "label_windows"}), rest
    assert not {r for r in rest if r.endswith("creep_free") or "sensor" in r or "input" in r
                or "augmented" in r}  # fmt: skip
    # the default run used the quick profile's choices: reference contact model, 0.25 rad squeeze
    base = read_parquet_metadata(workdir / "results" / "replay" / OBJECT / "replays_0.parquet")
    assert base["contact_model"] == "reference" and base["squeeze_rad"] == 0.25
    base_speeds = json.loads((workdir / "results" / "datasets" / "speeds.json").read_text())
    assert base_speeds["box_creep"]["speed"] > speeds["v_slip"]  # reference: creeps


@pytest.mark.workflow
def test_reference_energy_runs_through_replay(run, tmp_path):
    """Eq. 16's energy (the quick profile uses ours) through annealing and replay of one object,
    in a copy of the toy run: it reruns from annealing on, and a dry run shows the rest of the
    way (the other objects' annealing, labelling; the labelling stage reads replays, whatever
    energy chose their grasps). Not through the whole DAG: at toy scale, with the strict model
    and no squeeze too, its deep grasps leave no training window."""
    from graspstab.common.io import read_parquet_metadata

    workdir, env, config = run
    ref = copy_run(workdir, tmp_path / "ref_energy")
    replays = _object_replays(ref)
    proc = _snakemake(ref, *replays, *config, "energy=reference", env=env)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-4000:]
    jobs = listed_jobs(proc.stdout + proc.stderr)
    assert {j["rule"] for j in jobs} == {"anneal_grasps", "replay_grasps"}
    assert {j["wildcards"]["object"] for j in jobs} == {OBJECT}
    grasps = read_parquet_metadata(ref / "results" / "grasps" / OBJECT / "shard_0.parquet")
    assert grasps["provenance"]["params"]["energy"]["name"] == "reference"
    assert grasps["provenance"]["params"]["energy"]["weights"]["hpen"] == 0.0
    for path in replays:  # new grasps, new replays
        assert (ref / path).read_bytes() != (workdir / path).read_bytes(), path
    rest = _snakemake(ref, "results/datasets/speeds.json", "--dry-run", *config,
                      "energy=reference", env=env)  # fmt: skip
    assert rest.returncode == 0, rest.stdout[-3000:] + rest.stderr[-3000:]
    later = listed_jobs(rest.stdout)
    assert {"anneal_grasps", "replay_grasps", "label_windows"} <= {j["rule"] for j in later}
    again = {j["wildcards"]["object"] for j in later if j["rule"] in {"anneal_grasps",
                                                                        "replay_grasps"}}
    assert again and OBJECT not in again  # the other objects only: this one is done
    assert not {j["rule"] for j in later} & {"fetch_ycb_object", "build_hand",
                                              "preprocess_object"}  # fmt: skip


@pytest.mark.workflow
@pytest.mark.parametrize(
    ("override", "named"),
    [
        ("objects={items: {014_lemon: {split: training}}}", ["014_lemon", "'split'"]),
        ("labels={v_slip: .nan}", ["labels.v_slip = nan"]),
        ("labels={label_low: 0.7, label_high: 0.3}", ["labels.label_low", "label_high"]),
    ],
)
def test_bad_config_stops_at_load_time(tmp_path, asset_env, override, named):
    # a real run, not a dry one, with the assets at hand: it must stop before any job, leaving no
    # results/ behind
    proc = _snakemake(tmp_path, "results/report.html", "--config", override, env=asset_env)
    assert proc.returncode != 0
    out = proc.stdout + proc.stderr
    assert all(text in out for text in named), out[-2000:]
    assert not (tmp_path / "results").exists()


@pytest.mark.workflow
def test_learning_studies(run):
    import polars as pl
    import torch

    from graspstab.learning.models import build_model

    workdir, _, _ = run
    res = workdir / "results"
    for model in ("cnn", "gru", "lstm"):
        run_dir = res / "train" / "baseline" / model / "seed42"
        metrics = json.loads((run_dir / "metrics.json").read_text())
        assert metrics["family"] == model and metrics["window_steps"] == 400
        assert metrics["epochs_run"] <= 2 and metrics["val"]["n"] > 0 and metrics["test"]["n"] > 0
        assert set(metrics["test_objects"]) == {"077_rubiks_cube"}
        predictions = pl.read_parquet(run_dir / "predictions.parquet")
        assert set(predictions["split"]) == {"val", "test"}
        ckpt = torch.load(run_dir / "model.pt", weights_only=False)
        build_model(ckpt["model"]).load_state_dict(ckpt["state_dict"])  # loads as saved
        best = json.loads((res / "tune" / model / "best.json").read_text())
        assert best["spec"]["family"] == model and best["trials"]["complete"] >= 1
        for ms in (10, 20):
            sweep = res / "train" / "sweep" / model / f"w{ms}ms" / "seed42" / "metrics.json"
            assert json.loads(sweep.read_text())["window_steps"] == ms * 2
    baseline = pl.read_parquet(res / "studies" / "baseline" / "summary.parquet")
    assert baseline.height == 6  # three families x {val, test}
    latency = pl.read_parquet(res / "studies" / "latency.parquet")
    assert latency.height == 3 + 3 * 2 and (latency["median_ms"] > 0).all()
    splits = json.loads((res / "studies" / "splits" / "summary.json").read_text())
    assert splits["assignments"] == 2
    proxy = json.loads((res / "studies" / "proxy.json").read_text())
    assert proxy["test"]["n"] == metrics["test"]["n"]


def readme_monitor_example() -> str:
    """The README's example of loading an exported model and feeding it frames."""
    text = (REPO / "README.md").read_text()
    after = text[text.index("Load one and feed it frames:") :]
    return re.search(r"```python\n(.*?)```", after, flags=re.S).group(1)


@pytest.mark.workflow
def test_monitor_exports_and_grasp_level_evaluation(run):
    import polars as pl

    from graspstab.monitor.export import load_onnx, load_torchscript

    workdir, env, _ = run
    res = workdir / "results"
    summary = json.loads((res / "monitor" / "summary.json").read_text())
    assert set(summary["monitors"]) == {"cnn", "gru", "lstm", "proxy"}
    # held out: the lemon (validation, four shards of four) and the cube (test, two of four)
    replays = summary["replays"]
    assert 0 < replays["val"] <= 16 and 0 < replays["test"] <= 8
    for model in ("cnn", "gru", "lstm"):
        mine = summary["monitors"][model]
        metrics = json.loads((res / "train" / "sweep" / model / "w10ms" / "seed42" /
                              "metrics.json").read_text())  # fmt: skip
        assert mine["window_steps"] == 20
        assert mine["threshold"] == metrics["threshold"]["threshold"]
        for split in ("val", "test"):
            assert mine["splits"][split]["grasps"] == replays[split]
    episodes = pl.read_parquet(res / "monitor" / "episodes.parquet")
    assert episodes.height == 4 * (replays["val"] + replays["test"])
    # the onset is the replay's, whichever monitor reads it
    onsets = episodes.group_by("object", "grasp_id").agg(pl.col("onset").n_unique())
    assert onsets["onset"].max() == 1
    for name in ("baseline_cnn", "baseline_gru", "baseline_lstm"):
        export = res / "monitor" / "export" / name
        scorer = load_onnx(export / "model.onnx")
        assert scorer.constants.window_steps == 400
        assert load_torchscript(export / "model.torchscript.pt").constants.family == name[9:]
        assert json.loads((export / "constants.json").read_text())["threshold"] == (
            scorer.constants.threshold
        )
    choice = json.loads((res / "studies" / "sweep" / "summary.json").read_text())["choice"]
    pick = load_onnx(res / "monitor" / "export" / "pick" / "model.onnx").constants
    assert pick.family == choice["pick"]["family"]
    assert pick.window_steps == round(choice["pick"]["window_s"] / 5e-4)
    for figure in ("lead_times.png", "timeline.png"):
        assert (res / "figures" / "monitor" / figure).stat().st_size > 1000
    # the README's example runs as written in a finished run's directory
    proc = subprocess.run([sys.executable, "-c", readme_monitor_example()], cwd=workdir, env=env,
                          capture_output=True, text=True, timeout=300)  # fmt: skip
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert re.search(r"threshold \d\.\d{3}\n", proc.stdout)
    assert re.search(r"grasp \d+: (warning at \d\.\d{4} s|no warning in \d+ frames)", proc.stdout)


@pytest.mark.workflow
def test_sensor_robustness_study(run):
    """Every condition (clean, each curve's strengths, each preset) reaches every baseline model
    and the proxy, and the sweep models at the monitor's window; the report's section holds the
    tables and the curves; each augmentation mode is a run of its own."""
    import polars as pl

    workdir, _, _ = run
    res = workdir / "results"
    runs = pl.read_parquet(res / "studies" / "sensing" / "runs.parquet")
    quick = yaml.safe_load((REPO / "config" / "profile" / "quick.yaml").read_text())["sensing"]
    default = yaml.safe_load((REPO / "config" / "sensing" / "default.yaml").read_text())
    n = 1 + sum(len(v) for v in quick["curves"].values()) + len(default["presets"])
    # three families at seed 42, the LSTM trained through the sensors, and the proxy
    assert runs.height == n * 5
    assert set(runs.filter(pl.col("training") == "augmented")["family"]) == {"lstm"}
    assert set(runs["family"]) == {"cnn", "gru", "lstm", "proxy"}
    assert set(runs.filter(pl.col("kind") == "preset")["corruption"]) == set(default["presets"])
    clean = runs.filter((pl.col("kind") == "clean") & (pl.col("family") == "proxy"))["auprc"][0]
    proxy = json.loads((res / "studies" / "proxy.json").read_text())["test"]["auprc"]
    proxy = math.nan if proxy is None else proxy  # JSON null: undefined (one class in the split)
    assert clean == pytest.approx(proxy, abs=1e-9) or (math.isnan(clean) and math.isnan(proxy))
    html = (res / "report.html").read_text()
    section = html[html.index('id="sensing"') :]
    assert "Test AUPRC (%) per corruption and strength" in section
    assert "Test AUPRC (%) per sensor preset" in section and 'id="sensing-curves"' in section
    # the same conditions at the monitor's 0.01 s window: each family's sweep model, the proxy
    pick = pl.read_parquet(res / "studies" / "sensing" / "pick" / "runs.parquet")
    assert pick.height == n * 4 and set(pick["seed"]) == {42, -1}
    assert (pick.select("kind", "corruption").unique().height
            == runs.select("kind", "corruption").unique().height)  # fmt: skip
    assert "Test AUPRC (%) at the 0.01 s window" in section
    # one augmented run per mode (sensing.augment.modes): a corruption's mode adds its own run
    workdir, env, config = run
    jobs = _dry_jobs(workdir, [*config, "sensing={augment: {modes: [mixture, rate]}}"], env)
    aug = [j["wildcards"] for j in jobs if j["rule"] == "train_augmented_model"]
    assert aug == [{"mode": "rate", "model": "lstm", "seed": "42"}]  # the mixture's is done
    assert "evaluate_sensor_robustness" in {j["rule"] for j in jobs}


@pytest.mark.workflow
def test_input_audit(run):
    """The quick profile's input audit: the LSTM on forces (the baseline run), normal, shear,
    normal + the shear's two components and forces + object state, with 10, 5, 5, 15 and 16
    inputs; 16 give table 4.2's LSTM count."""
    workdir, _, _ = run
    res = workdir / "results"
    info = json.loads((res / "studies" / "inputs" / "summary.json").read_text())
    shapes = {r["input_set"]: r for r in info["shapes"] if r["family"] == "lstm"}
    assert {k: v["inputs"] for k, v in shapes.items()} == {
        "forces": 10, "normal": 5, "shear": 5, "tangential": 15, "object_state": 16}  # fmt: skip
    assert shapes["object_state"]["parameters"] == 25_217  # table 4.2
    assert shapes["forces"]["parameters"] == 23_681
    forces = json.loads((res / "train" / "baseline" / "lstm" / "seed42" / "metrics.json")
                        .read_text())["test"]["auprc"]  # fmt: skip
    row = [r for r in info["summary"] if r["input_set"] == "forces" and r["split"] == "test"][0]
    assert row["auprc_mean"] == pytest.approx(forces, nan_ok=True)
    html = (res / "report.html").read_text()
    assert 'id="input-audit"' in html and "Input audit: test AUPRC and parameters" in html


@pytest.mark.workflow
def test_learning_rate_change_reruns_that_model_only(run):
    workdir, env, config = run
    changed = [*config, "model={gru: {learning_rate: 0.002}}"]
    proc = _snakemake(workdir, "results/report.html", "--dry-run", *changed, env=env)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    jobs = set(re.findall(r"^(\w+)\s+\d+$", proc.stdout, flags=re.M)) - {"total"}
    assert {"train_model", "tune_model", "train_sweep_model", "aggregate_baseline"} <= jobs
    assert {"aggregate_sweep", "measure_latency", "report"} <= jobs
    # the split study trains the LSTM, and nothing upstream of training depends on a model
    assert not jobs & {"train_split_model", "aggregate_splits", "label_windows", "replay_grasps"}
    models = set(re.findall(r"wildcards: model=(\w+)", proc.stdout))
    assert models == {"gru"}


EXPENSIVE = {"preprocess_object", "anneal_grasps", "replay_grasps", "tune_model", "train_model",
             "train_sweep_model", "train_split_model", "export_monitor",
             "evaluate_monitor"}  # fmt: skip
# (export_pick is cached too, but its input, the sweep summary, holds measured latencies, so it
# differs between runs and the job rightly recomputes: the latency-aware pick may change with it)


@pytest.mark.workflow
def test_annealing_parameter_reruns_from_annealing_on(run):
    workdir, env, config = run
    changed = _with(config, TOY_SYNTHESIS, TOY_SYNTHESIS.replace("1500", "1400"))
    jobs = _dry_jobs(workdir, changed, env)
    rules = {j["rule"] for j in jobs}
    anneal = {(j["wildcards"]["object"], j["wildcards"]["shard"]) for j in jobs
              if j["rule"] == "anneal_grasps"}  # fmt: skip
    # two shards each, four for the validation object (toy synthesis.split_shards)
    shards = {"061_foam_brick": 2, "014_lemon": 4, "077_rubiks_cube": 2}
    assert anneal == {(o, str(k)) for o, n in shards.items() for k in range(n)}
    assert sum(j["rule"] == "replay_grasps" for j in jobs) == 8
    assert {"label_windows", "train_model", "tune_model", "report"} <= rules
    assert not rules & {"preprocess_object", "build_hand", "fetch_ycb_object",
                        "fetch_hand_description", "plot_objects", "plot_hand"}  # fmt: skip


@pytest.mark.workflow
def test_adding_an_object_runs_only_its_jobs_plus_downstream(run):
    workdir, env, config = run
    added = "010_potted_meat_can"
    changed = _with(config, OBJECTS, OBJECTS.replace("]", f",{added}]"))
    jobs = _dry_jobs(workdir, changed, env)
    per_object = [j for j in jobs if "object" in j["wildcards"]]
    assert {j["wildcards"]["object"] for j in per_object} == {added}
    assert {j["rule"] for j in per_object} == {
        "fetch_ycb_object", "preprocess_object", "anneal_grasps", "replay_grasps",
        "replay_grasps_creep_free", "summarise_grasps"}  # fmt: skip
    # a validation object: the toy's split_shards gives it four shards
    assert sum(j["rule"] == "anneal_grasps" for j in per_object) == 4
    rules = {j["rule"] for j in jobs}
    assert "build_hand" not in rules
    assert {"label_windows", "aggregate_baseline", "report"} <= rules  # downstream aggregation


@pytest.mark.workflow
def test_no_two_jobs_write_the_same_file(run):
    workdir, env, config = run
    jobs = _dry_jobs(workdir, config, env, "--forceall")
    declared = [p for j in jobs for f in ("output", "log", "benchmark") for p in j[f]]
    duplicates = {p for p in declared if declared.count(p) > 1}
    assert not duplicates
    # and nothing under results/ is written that no job declares (the Optuna database is the one
    # undeclared file: one tune_model job owns each)
    declared_paths = {workdir / p for p in declared}
    undeclared = []
    for path in (workdir / "results").rglob("*"):
        if path.is_file() and not any(d == path or d in path.parents for d in declared_paths):
            undeclared.append(str(path.relative_to(workdir)))
    assert all(re.fullmatch(r"results/tune/\w+/study\.sqlite", p) for p in undeclared), undeclared
    assert not list((workdir / "results").rglob("*.tmp"))  # no leftover partial files


def _assert_same_replays(reference: Path, other: Path, under: str = "") -> None:
    """Every replay output of ``other`` (under ``results/replay/<under>``) equals the
    reference's, NaN for NaN, except the wall-clock columns."""
    import numpy as np
    import polars as pl

    files = sorted((reference / "results" / "replay" / under).rglob("*.*"))
    assert files
    assert sorted((other / "results" / "replay" / under).rglob("*.*")) == [
        other / f.relative_to(reference) for f in files
    ]
    for path in files:
        twin = other / path.relative_to(reference)
        if path.suffix == ".parquet":
            a, b = pl.read_parquet(path), pl.read_parquet(twin)
            assert a.columns == b.columns, path
            for col in (c for c in a.columns if "wall" not in c):
                np.testing.assert_array_equal(a[col].to_numpy(), b[col].to_numpy(), err_msg=col)
        else:
            with np.load(path) as a, np.load(twin) as b:
                assert a.files == b.files, path
                for key in a.files:
                    np.testing.assert_array_equal(a[key], b[key], err_msg=f"{path}: {key}")


@pytest.mark.workflow
def test_run_killed_mid_replay_resumes_to_identical_outputs(run, tmp_path):
    """SIGKILL the whole Snakemake process group while a replay job is mid-shard, restart,
    compare with the uninterrupted run. The kill point is fixed, not raced: a gate
    (tests/replay_gate.py, as the run's sitecustomize) holds the first replay job to reach its
    second grasp until the kill, after it says so in a file."""
    import signal
    import time

    workdir, env, config = run
    killed = tmp_path / "wf"
    # Everything up to annealing, with Snakemake's metadata; no replay outputs and no cache, so
    # the restarted run has to replay again.
    shutil.copytree(workdir, killed, symlinks=True,
                    ignore=shutil.ignore_patterns(".graspstab-cache", "replay", "replay_grasps",
                                                  "locks", "incomplete"))  # fmt: skip
    # one object's replay tables: two shards, so both cores replay and one is held at the gate
    tables = (workdir / "results" / "replay" / OBJECT).glob("replays_*.parquet")
    targets = sorted(str(p.relative_to(workdir)) for p in tables)
    assert len(targets) == 2
    site, gate = tmp_path / "site", tmp_path / "gate"
    site.mkdir()
    gate.mkdir()
    shutil.copyfile(REPO / "tests" / "replay_gate.py", site / "sitecustomize.py")
    path = os.pathsep.join(p for p in (str(site), env.get("PYTHONPATH")) if p)
    gated = dict(env, PYTHONPATH=path, GRASPSTAB_TEST_REPLAY_GATE=str(gate))
    cmd = [sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile"), "-d", str(killed),
           "--cores", "2", *targets, *config]  # fmt: skip
    log = tmp_path / "killed_run.log"
    with log.open("w") as out:
        proc = subprocess.Popen(cmd, env=gated, stdout=out, stderr=subprocess.STDOUT,
                                start_new_session=True)  # fmt: skip
    try:
        # the gated job cannot finish, so neither can the run: wait for the gate's word (the
        # limit only turns a run that dies or hangs before the gate into a failure)
        deadline = time.monotonic() + 600
        while not (gate / "blocked").exists():
            ended = proc.poll() is not None
            assert not ended, f"the run ended before the gate: {log.read_text()[-3000:]}"
            assert time.monotonic() < deadline, "no replay reached the gate in 600 s"
            time.sleep(0.05)
        assert proc.poll() is None
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=30)
    done = [t for t in targets if (killed / t).exists()]
    assert len(done) < len(targets)  # the gated shard at least was interrupted
    # a hard kill leaves Snakemake's lock behind: release it as a user would (README)
    unlock = _snakemake(killed, "--unlock", *targets, *config, env=env)
    assert unlock.returncode == 0, unlock.stderr[-3000:]
    resumed = _snakemake(killed, *targets, *config, env=env)
    assert resumed.returncode == 0, resumed.stdout[-3000:] + resumed.stderr[-3000:]
    assert not list((killed / "results").rglob("*.tmp"))
    _assert_same_replays(workdir, killed, OBJECT)


def _expensive_outputs(workdir: Path, jobs: list[dict]) -> dict[str, bytes]:
    return {p: (workdir / p).read_bytes() for j in jobs if j["rule"] in EXPENSIVE
            for p in j["output"] if (workdir / p).is_file()}  # fmt: skip


@pytest.mark.workflow
def test_reverted_change_is_found_by_content(run, tmp_path):
    """Change an annealing parameter, run, revert it, run again: every expensive job of the
    second run restores its earlier outputs, byte for byte, instead of recomputing. On a copy of
    the toy run (its results, cache and Snakemake metadata), which the other tests never see."""
    shared, env, config = run
    workdir = copy_run(shared, tmp_path / "wf")
    all_jobs = _dry_jobs(workdir, config, env, "--forceall")
    before = _expensive_outputs(workdir, all_jobs)
    changed = _with(config, TOY_SYNTHESIS, TOY_SYNTHESIS.replace("1500", "1400"))
    # the changed run only as far as one object's replays: enough to change its grasps and
    # replays (labelling and the learning jobs then rerun on the reverted run's inputs, by mtime),
    # at a fraction of a whole run's cost
    replays = _object_replays(workdir)
    assert len(replays) == 4, replays  # two shards: a table and traces each
    proc = _snakemake(workdir, *replays, *changed, env=env)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert _expensive_outputs(workdir, all_jobs) != before  # the change did change the results

    # the reverted run asks for every expensive job's outputs (and so runs whatever they need),
    # not for the report: the cheap jobs downstream of them (figures, the extensions' studies,
    # the report) have no cache and would only recompute
    targets = sorted({p for j in all_jobs if j["rule"] in EXPENSIVE for p in j["output"]})
    proc = _snakemake(workdir, *targets, *config, env=env)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    ran = [j for j in listed_jobs(proc.stdout + proc.stderr) if j["rule"] in EXPENSIVE]
    # every expensive rule downstream of annealing ran, and each job restored its outputs
    assert {j["rule"] for j in ran} == EXPENSIVE - {"preprocess_object"}
    for job in ran:
        log_text = (workdir / job["log"][0]).read_text()
        assert log_text.startswith("graspstab cache: restored"), (job, log_text[:500])
    assert _expensive_outputs(workdir, all_jobs) == before
    again = _snakemake(workdir, *targets, "--dry-run", *config, env=env)
    assert "Nothing to be done" in again.stdout + again.stderr
