"""The report (issue 7): strict JSON, the headline, funnel, stage-time and DAG helpers against hand
computations, and whole reports built by the real write_report and rendered in headless Chromium
(no console errors, a non-blank screenshot, every section id, every embedded image decodes)."""

from __future__ import annotations

import base64
import io
import json
import math
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import polars as pl  # noqa: E402
import pytest  # noqa: E402
from PIL import Image  # noqa: E402

from graspstab.common.io import read_json, write_json, write_parquet  # noqa: E402
from graspstab.config import load_config  # noqa: E402
from graspstab.evaluation import aggregate, studies  # noqa: E402
from graspstab.figures.presentation import LEARNING_FIGURES  # noqa: E402
from graspstab.labels.anatomy import summarise  # noqa: E402
from graspstab.labels.funnel import funnel, summarise_funnel  # noqa: E402
from graspstab.metrics.classification import (  # noqa: E402
    binary_metrics,
    per_object_metrics,
    select_threshold,
    threshold_grid,
)
from graspstab.replay.outcomes import replay_outcomes, summarise_replays  # noqa: E402
from graspstab.report import dag  # noqa: E402
from graspstab.report.headline import (  # noqa: E402
    headline_rows,
    run_scale,
    scale_sentence,
)
from graspstab.report.provenance import stage_times  # noqa: E402
from graspstab.report.write_report import SECTION_IDS, write_report  # noqa: E402
from tests.conftest import REPO, SCHEMA  # noqa: E402
from tests.study_layout import study_artefacts  # noqa: E402

FAMILIES = ("cnn", "gru", "lstm")
OBJECTS = {"014_lemon": "train", "013_apple": "val", "077_rubiks_cube": "test"}


def _reject(token: str) -> Any:
    raise ValueError(f"non-standard JSON constant {token}")


# --------------------------------------------------------------------------- strict JSON


def test_write_json_writes_strict_json(tmp_path: Path) -> None:
    data = {
        "nan": float("nan"),
        "inf": float("inf"),
        "ninf": -math.inf,
        "np": np.float32("nan"),
        "array": np.array([1.0, np.nan, 2.5]),
        "nested": [{"x": (np.float64(np.inf), 3)}],
        "ok": np.int64(7),
    }
    write_json(tmp_path / "x.json", data)
    text = (tmp_path / "x.json").read_text()
    parsed = json.loads(text, parse_constant=_reject)  # a strict parser accepts it
    assert parsed == {
        "nan": None, "inf": None, "ninf": None, "np": None, "array": [1.0, None, 2.5],
        "nested": [{"x": [None, 3]}], "ok": 7,
    }  # fmt: skip
    assert "NaN" not in text and "Infinity" not in text


def test_undefined_metrics_survive_the_null_round_trip(tmp_path: Path) -> None:
    """metrics.json stores an undefined AUPRC as null; the studies read it back as NaN."""
    rec = _record("gru", 42, val_unstable=0.0)
    write_json(tmp_path / "m.json", rec)
    back = read_json(tmp_path / "m.json")
    assert back["val"]["auprc"] is None
    runs = aggregate.run_rows([back], [{}])
    assert math.isnan(runs.filter(pl.col("split") == "val")["auprc"][0])


# ------------------------------------------------------------------------------ headline


def _runs_frame(rows: list[dict[str, Any]]) -> pl.DataFrame:
    """A runs table with just what the headline reads (and undefined_as_nan needs)."""
    base = {"tp": 1, "fp": 1, "fn": 1, "precision": 0.5, "recall": 0.5, "f1": 0.5,
            "n": 100, "n_unstable": 10, "window_s": 0.2}  # fmt: skip
    return pl.DataFrame([{**base, **r} for r in rows])


def _studies_tree(root: Path) -> Any:
    """The headline's artefacts (baseline and sweep runs, proxy, splits summary) below ``root``."""
    s = root / "studies"
    rows = [
        {"family": "cnn", "seed": 42, "split": "test", "auprc": 0.80, "auroc": 0.7},
        {"family": "cnn", "seed": 43, "split": "test", "auprc": 0.90, "auroc": 0.9},
        # the GRU's test split holds no unstable window: its AUPRC is undefined, not 0
        {"family": "gru", "seed": 42, "split": "test", "auprc": math.nan, "auroc": math.nan,
         "n_unstable": 0},
        {"family": "gru", "seed": 43, "split": "test", "auprc": math.nan, "auroc": math.nan,
         "n_unstable": 0},
        {"family": "lstm", "seed": 42, "split": "test", "auprc": 0.5, "auroc": 0.6},
    ]  # fmt: skip
    write_parquet(s / "baseline" / "runs.parquet", _runs_frame(rows))
    # the seed summary the aggregation job writes beside the runs (the headline reads it)
    write_parquet(s / "baseline" / "summary_defined.parquet",
                  aggregate.seed_summary(_runs_frame(rows), ["family", "split"]))  # fmt: skip
    write_json(s / "proxy.json", {"test": {"auprc": math.nan, "n": 50, "n_unstable": 0}})
    write_json(s / "splits" / "summary.json",
               {"assignments": 3, "defined": 1, "mean": 0.25, "std": math.nan})  # fmt: skip
    sweep = [{"family": "lstm", "seed": k, "split": "val", "auprc": v, "auroc": 0.5,
              "window_s": w} for k, (v, w) in enumerate([(0.6, 0.02), (0.7, 0.05)])]  # fmt: skip
    write_parquet(s / "sweep" / "runs.parquet", _runs_frame(sweep))
    write_parquet(s / "sweep" / "summary_defined.parquet",
                  aggregate.seed_summary(_runs_frame(sweep), ["family", "window_s", "split"]))
    return study_artefacts(root)


def test_headline_values_and_undefined_reasons(tmp_path: Path) -> None:
    rows = {r[1]: r[2] for r in headline_rows(_studies_tree(tmp_path))}
    cnn = next(v for k, v in rows.items() if k.startswith("CNN test AUPRC"))
    assert cnn == f"85.00 ± {100 * np.std([0.8, 0.9], ddof=1):.2f} %"  # by hand: 7.07
    gru = next(v for k, v in rows.items() if k.startswith("GRU test AUPRC at the 0.20"))
    assert gru == "undefined (the test split holds no unstable window)"
    assert rows["GRU test AUROC at the baseline window"] == gru
    lstm = next(v for k, v in rows.items() if k.startswith("LSTM test AUPRC"))
    assert lstm == "50.00 % (std undefined: 1 seed defined it)"
    assert rows["Friction-ratio proxy, test AUPRC"] == (
        "undefined (the test split holds no unstable window)"
    )
    split = next(v for k, v in rows.items() if k.startswith("Split robustness"))
    assert split == "25.00 % (std undefined: 1 of 3 assignments defined)"
    sweep = next(v for k, v in rows.items() if k.startswith("LSTM at a 0.01 s"))
    assert sweep.startswith("undefined (LSTM at 0.01 s is not in this run's sweep")
    assert "0.02, 0.05" in sweep
    for value in rows.values():  # an undefined value never prints as a number
        assert not re.match(r"^0(\.0+)? ?%", value), value


def test_headline_names_missing_artefacts(tmp_path: Path) -> None:
    rows = headline_rows(study_artefacts(tmp_path))
    assert len(rows) == 8
    assert all(r[2].startswith("undefined (") and "not produced" in r[2] for r in rows)
    assert all(r[4] == "undefined" for r in rows)
    assert [r[3] for r in rows] == [
        "98.43 ± 0.05 %", "97.78 ± 0.07 %", "96.27 %", "98.03 %", "98.34 %", "98.41 %",
        "97.14 ± 2.49 %", "98.747 ± 0.022 %",
    ]  # fmt: skip


def test_scale_sentence_warns_in_bold_for_quick_runs() -> None:
    config = {"profile_name": "quick", "train": {"seeds": [42, 43], "max_epochs": 8},
              "tune": {"trials": 4}}  # fmt: skip
    dataset = {"splits": {"train": {"grasps": 5, "stable": 90, "unstable": 10},
                          "val": {"grasps": 2, "stable": 30, "unstable": 0},
                          "test": {"grasps": 3, "stable": 40, "unstable": 5}}}  # fmt: skip
    scale = run_scale(config, 3, {"annealed": 48, "usable": 10}, dataset)  # the funnel's totals
    assert scale["candidate_grasps"] == 48 and scale["usable_grasps"] == 10
    assert scale["windows"] == {"train": 100, "val": 30, "test": 45}
    text = scale_sentence(scale)
    assert "3 objects" in text and "48 candidate grasps" in text and "10 usable grasps" in text
    assert "100 train / 30 val / 45 test windows" in text and "2 training seeds (42, 43)" in text
    assert "at most 8 epochs" in text and "4 Optuna trials" in text
    assert re.search(r"<b>Quick-profile numbers come from a reduced scale[^<]*not a reproduction",
                     text)  # fmt: skip
    assert "The test split is 11.1 % unstable" in text  # 5 of 45, the chance AUPRC
    thesis = scale_sentence({**scale, "profile": "thesis"})
    assert "reduced scale" not in thesis and "reference's scale" in thesis
    # the protocol's deviations are named (here: none given, so unknown names count as such)
    full = load_config(REPO / "config", SCHEMA, check_files=False)
    proto = run_scale(full, 3, None, dataset)["protocol"]
    assert proto["contact"] == "reference" and proto["energy"] == "hpen"
    assert proto["deviations"] == ["energy hpen (w_fc 0.01 and E_hpen)", "a 0.25 rad squeeze"]
    ref = run_scale(load_config(REPO / "config", SCHEMA, {"profile": "thesis"},
                                check_files=False), 3, None, dataset)["protocol"]  # fmt: skip
    assert ref["deviations"] == [] and "the reference's choices throughout" in scale_sentence(
        {**scale, "protocol": ref}
    )


def test_headline_gap_column() -> None:
    from graspstab.report.headline import Figure, gap_text

    assert gap_text(Figure(0.9), "98.43 ± 0.05 %") == "-8.43"
    assert gap_text(Figure(0.99, digits=3), "98.747 ± 0.022 %") == "+0.253"
    assert gap_text(Figure(reason="x"), "96.27 %") == "undefined"


# -------------------------------------------------------------------------------- funnel


def _replays(path: Path, obj: str, held: list[bool], diverged: list[bool]) -> Path:
    n = len(held)
    frame = pl.DataFrame({
        "grasp_id": list(range(n)), "object": [obj] * n, "shard": [0] * n,
        "stop_reason": ["completed" if h else "contact_lost" for h in held],
        "diverged": diverged, "held_at_end": held, "max_penetration": [0.001] * n,
        "duration_s": [1.0] * n,
    })  # fmt: skip
    write_parquet(path, frame)
    return path


def test_funnel_counts_per_object_and_total(tmp_path: Path) -> None:
    summaries = [{"object_id": "a_obj", "grasps": 4}, {"object_id": "b_obj", "grasps": 3}]
    tables = [
        _replays(tmp_path / "a0.parquet", "a_obj", [True, False], [False, False]),
        _replays(tmp_path / "a1.parquet", "a_obj", [True, True], [False, True]),
        _replays(tmp_path / "b0.parquet", "b_obj", [False, False, True], [True, False, False]),
    ]
    empty = {"grasps": 0, "stable": 0, "unstable": 0}
    dataset = {"objects": {
        "a_obj": {"train": {"grasps": 2, "stable": 30, "unstable": 4}, "val": empty,
                  "test": empty},
        "b_obj": {"train": empty, "val": empty,
                  "test": {"grasps": 1, "stable": 9, "unstable": 1}},
    }}  # fmt: skip
    outcomes = replay_outcomes(pl.concat([pl.read_parquet(t) for t in tables]))
    rows = funnel(summaries, outcomes, dataset)
    assert rows == [
        {"object": "a_obj", "annealed": 4, "replayed": 4, "diverged": 1, "held": 3,
         "usable": 2, "windows": 34, "unstable": 4},
        {"object": "b_obj", "annealed": 3, "replayed": 3, "diverged": 1, "held": 1,
         "usable": 1, "windows": 10, "unstable": 1},
        {"object": None, "annealed": 7, "replayed": 7, "diverged": 2, "held": 4,
         "usable": 3, "windows": 44, "unstable": 5},
    ]  # fmt: skip
    no_dataset = funnel(summaries, outcomes, None)
    assert no_dataset[-1]["usable"] is None and no_dataset[-1]["replayed"] == 7


# ------------------------------------------------------------------------ stage times


def _bench(path: Path, seconds: float, rss: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(
        "s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\tio_out\tmean_load\tcpu_time\n"
        f"{seconds}\t0:00:00\t{rss}\t1\t1\t1\t0\t0\t50\t1\n"
    )
    return path


def test_stage_times_match_hand_sums(tmp_path: Path) -> None:
    b = tmp_path / "benchmarks"
    files = {
        "anneal_grasps": [_bench(b / "anneal_grasps" / f"x_shard_{k}.tsv", s, r)
                          for k, (s, r) in enumerate([(10.0, "100.5"), (30.0, "NA"),
                                                      (20.0, "300.0")])],
        "build_hand": [_bench(b / "build_hand" / "hand.tsv", 40.0, "50.0"),
                       b / "build_hand" / "never_written.tsv"],
    }  # fmt: skip
    rows = stage_times(files, {"anneal_grasps": 3, "build_hand": 1, "aggregate": 1},
                       order=["build_hand", "anneal_grasps", "aggregate"])  # fmt: skip
    assert [r["rule"] for r in rows] == ["build_hand", "anneal_grasps", "aggregate"]
    hand, anneal, agg = rows
    assert anneal["jobs"] == 3 and anneal["job_s"] == pytest.approx(60.0)
    assert anneal["share"] == pytest.approx(60.0 / 100.0)
    assert anneal["max_s"] == 30.0 and anneal["max_job"] == "x_shard_1"
    assert anneal["peak_rss_mb"] == pytest.approx(300.0)  # "NA" is skipped, not read as 0
    assert hand["jobs"] == 1 and hand["missing"] == 1 and hand["share"] == pytest.approx(0.4)
    assert agg["jobs"] == 0 and agg["dag_jobs"] == 1 and agg["job_s"] is None


# ----------------------------------------------------------------------------------- DAG

# Snakemake's dot format (9.x): a rule graph and the job graph of the same toy workflow.
RULEGRAPH = """digraph snakemake_dag {
    graph[bgcolor=white, margin=0];
    node[shape=box, style=rounded, fontname=sans,                 fontsize=10, penwidth=2];
    edge[penwidth=2, color=grey];
\t0[label = "report", color = "0.48 0.6 0.85", style="rounded"];
\t1[label = "anneal_grasps", color = "0.10 0.6 0.85", style="rounded"];
\t2[label = "preprocess_object", color = "0.43 0.6 0.85", style="rounded"];
\t3[label = "build_hand", color = "0.12 0.6 0.85", style="rounded"];
\t1 -> 0
\t2 -> 0
\t3 -> 0
\t2 -> 1
\t3 -> 1
}
"""
JOBGRAPH = """digraph snakemake_dag {
    graph[bgcolor=white, margin=0];
\t0[label = "report", color = "0.48 0.6 0.85", style="rounded"];
\t1[label = "anneal_grasps\\nobject: a_obj\\nshard: 0", color = "0.1 0.6 0.85", style="rounded"];
\t2[label = "anneal_grasps\\nobject: a_obj\\nshard: 1", color = "0.1 0.6 0.85", style="rounded"];
\t3[label = "preprocess_object\\nobject: a_obj", color = "0.4 0.6 0.85", style="rounded"];
\t4[label = "build_hand", color = "0.12 0.6 0.85", style="rounded"];
\t1 -> 0
\t2 -> 0
\t3 -> 1
\t3 -> 2
\t4 -> 1
\t4 -> 2
\t3 -> 0
}
"""


def test_dag_parsing_of_snakemake_dot() -> None:
    graph = dag.rule_graph(RULEGRAPH)
    assert set(graph.nodes) == {"report", "anneal_grasps", "preprocess_object", "build_hand"}
    assert set(graph.edges) == {
        ("anneal_grasps", "report"), ("preprocess_object", "report"), ("build_hand", "report"),
        ("preprocess_object", "anneal_grasps"), ("build_hand", "anneal_grasps"),
    }  # fmt: skip
    assert set(dag.rule_graph(JOBGRAPH).edges) <= set(graph.edges)  # jobs collapse onto rules
    counts = dag.job_counts(JOBGRAPH)
    assert counts == {"report": 1, "anneal_grasps": 2, "preprocess_object": 1, "build_hand": 1}
    assert dag.layers(graph) == {"build_hand": 0, "preprocess_object": 0, "anneal_grasps": 1,
                                 "report": 2}  # fmt: skip
    text = dag.overview_text(graph, counts)
    assert "4 rules as 5 jobs" in text and "anneal_grasps (2)" in text
    png = Image.open(io.BytesIO(dag.draw_rule_graph(graph, counts, dpi=60)))
    assert png.format == "PNG" and np.asarray(png.convert("L")).std() > 0


def test_dot_with_undeclared_node_is_an_error() -> None:
    with pytest.raises(ValueError, match="undeclared"):
        dag.parse_dot('digraph d {\n\t0[label = "a"];\n\t1 -> 0\n}')


@pytest.fixture(scope="session")
def snakemake_graphs(
    tmp_path_factory: pytest.TempPathFactory, bare_env: dict[str, str]
) -> dict[str, Path]:
    """Snakemake's own --rulegraph and --dag of this workflow (default config), made exactly as
    rule rulegraph makes them (a few seconds; nothing runs, so no assets are needed)."""
    out = tmp_path_factory.mktemp("graphs")
    env = bare_env
    paths = {}
    for kind in ("rulegraph", "dag"):
        proc = subprocess.run(
            [sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile"), "-d", str(out),
             "--nolock", "--forceall", "results/report.html", f"--{kind}"],
            capture_output=True, text=True, env=env, timeout=300,
        )  # fmt: skip
        assert proc.returncode == 0, proc.stderr[-3000:]
        paths[kind] = out / f"{kind}.dot"
        paths[kind].write_text(proc.stdout)
    return paths


def test_parses_snakemakes_own_rule_graph(snakemake_graphs: dict[str, Path]) -> None:
    """The parser reads the installed Snakemake's output: every rule, report the only sink."""
    graph, counts = dag.read_graph(snakemake_graphs["rulegraph"], snakemake_graphs["dag"])
    assert {"report", "rulegraph", "anneal_grasps", "replay_grasps", "train_model"} <= set(graph)
    assert [n for n in graph if graph.out_degree(n) == 0] == ["report"]
    assert set(counts) == set(graph.nodes)
    assert set(dag.rule_graph(snakemake_graphs["dag"].read_text()).edges) == set(graph.edges)
    assert counts["report"] == 1 and counts["anneal_grasps"] > 1


# --------------------------------------------------------------------- report fixtures


def _png(path: Path, seed: int) -> Path:
    rng = np.random.default_rng(seed)
    fig, ax = plt.subplots(figsize=(3, 2))
    ax.plot(rng.normal(size=20))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=40)
    plt.close(fig)
    return path


def _record(family: str, seed: int, val_unstable: float, **extra: Any) -> dict[str, Any]:
    """A metrics.json record as train_model writes it, from synthetic scores."""
    rng = np.random.default_rng([seed, FAMILIES.index(family), int(100 * val_unstable)])
    rec: dict[str, Any] = {
        "family": family,
        "seed": seed,
        "parameters": 1000,
        "seconds_per_epoch": 1.0,
        "best_epoch": 2,
        "window_steps": 400,
    }
    data = {}
    for split, frac in (("val", val_unstable), ("test", 0.3)):
        labels = (rng.random(80) < frac).astype(np.int8)
        probs = 1 / (1 + np.exp(-rng.normal(2.0 * (2 * labels - 1), 1.5)))
        data[split] = (labels, probs)
    choice = select_threshold(data["val"][1], data["val"][0], threshold_grid())
    rec["threshold"] = {**vars(choice), "min_recall": 0.9}
    obj = {"val": "013_apple", "test": "077_rubiks_cube"}
    for split, (labels, probs) in data.items():
        rec[split] = binary_metrics(probs, labels, choice.threshold)
        rec[f"{split}_objects"] = per_object_metrics(
            probs, labels, np.array([obj[split]] * len(labels)), choice.threshold
        )
    return {**rec, **extra}


def _block(n: int, pos: int, auprc: float | None = None, auroc: float | None = None) -> dict:
    """A still-now (moving-now) block as evaluation.detection.ranked writes it (null: NaN)."""
    return {"n": n, "n_unstable": pos, "chance": pos / n if n else None, "auprc": auprc,
            "auroc": auroc}  # fmt: skip


#: Planted still-now test blocks of the baseline runs per (family, seed): the CNN's AUPRC 0.61 and
#: 0.63 (62.00 ± 1.41 %), the GRU's still-now test windows never become unstable (undefined), the
#: LSTM's 0.5 in both seeds. Validation never slips: every still-now validation metric undefined.
STILL = {
    ("cnn", 42): _block(40, 10, 0.61, 0.71), ("cnn", 43): _block(40, 10, 0.63, 0.73),
    ("gru", 42): _block(40, 0), ("gru", 43): _block(40, 0),
    ("lstm", 42): _block(40, 10, 0.5, 0.55), ("lstm", 43): _block(40, 10, 0.5, 0.55),
}  # fmt: skip
#: The proxy's record beside its all-windows block: still now and the persistence oracle.
PROXY_STILL = {
    "test_still": _block(40, 10, 0.4444, 0.5555), "test_moving": _block(125, 0),
    "persistence": {"test": _block(165, 10, 0.7777, 0.8888),
                    "test_still": _block(40, 10, 0.25, 0.5)},
}  # fmt: skip


def _motion_records(family: str, seed: int) -> dict[str, Any]:
    return {"test_still": STILL[(family, seed)], "val_still": _block(30, 0),
            "test_moving": _block(40, 10, 0.9, 0.9), "val_moving": _block(25, 0)}  # fmt: skip


def _monitor_artefacts(root: Path, figs: dict[str, Path]) -> dict[str, Path]:
    """The streaming monitor's artefacts as rule report gets them: a summary with one failing
    grasp warned in time per split and no stable grasp (its rates undefined), two figures and
    one export's files."""
    from graspstab.monitor.constants import MonitorConstants, write_constants
    from graspstab.monitor.episodes import evaluate_episode, summarise_episodes

    u = np.zeros(3000, dtype=np.uint8)
    u[2000:] = 1
    warning = np.zeros(3000, dtype=bool)
    warning[1500:] = True
    one = evaluate_episode(warning, u, 0, 3000, contact_lost=False, dt=5e-4, offset_s=0.1,
                           horizon_s=0.15, object_id="o", grasp_id=0, split="test")  # fmt: skip
    split = summarise_episodes([one])
    monitors = {m: {"family": m, "window_steps": 20, "threshold": 0.4,
                    "splits": {"val": split, "test": split}}
                for m in ("cnn", "gru", "lstm", "proxy")}  # fmt: skip
    write_json(root / "summary.json", {
        "settings": {"stride": 10, "stride_s": 0.005, "debounce": 1, "dt": 5e-4, "window_s": 0.01,
                     "offset_s": 0.1, "horizon_s": 0.15, "v_slip": 0.0012},
        "replays": {"val": 1, "test": 1}, "monitors": monitors,
        "timeline": {"monitor": "lstm", "object": "o", "grasp_id": 0, "split": "test"},
    })  # fmt: skip
    export = root / "export" / "pick"
    write_constants(
        export / "constants.json",
        MonitorConstants(np.zeros((5, 2)), np.ones((5, 2)), 0.4, 20, family="lstm"),
    )
    for name in ("model.onnx", "model.torchscript.pt"):
        (export / name).write_bytes(b"0" * 2048)
    return {"summary": root / "summary.json", "leads_figure": _png(root / "leads.png", 40),
            "timeline_figure": _png(root / "timeline.png", 41),
            **{f"export_pick_{k}": export / n for k, n in (
                ("constants", "constants.json"), ("onnx", "model.onnx"),
                ("torchscript", "model.torchscript.pt"))}}  # fmt: skip


def _synthetic_results(root: Path, graphs: dict[str, Path]) -> dict[str, Any]:
    """A small results tree with every artefact write_report reads, and its keyword arguments.
    Validation never slips (as in a quick run), so undefined values must render as such."""
    r = root / "results"
    figs = {k: _png(r / "figures" / f"{k}.png", i) for i, k in enumerate(
        ["objects", "hand_candidates", "hand_capsules", "pregrasp", "grasp_gallery",
         "energy_histograms", "replay_trace", "window", "unstable_speeds"])}  # fmt: skip
    learning = {k: _png(r / "figures" / "learning" / f"{k}.png", 20 + i)
                for i, k in enumerate(LEARNING_FIGURES)}  # fmt: skip
    metas, summaries, replays, bench = [], [], [], {}
    q = {"q05": 0.001, "q50": 0.002, "q95": 0.004}
    for i, (obj, _) in enumerate(OBJECTS.items()):
        metas.append(r / "objects" / obj / "meta.json")
        write_json(metas[-1], {"object_id": obj, "mass": 0.1, "volume": 1e-4,
                               "extents": [0.05, 0.06, 0.07], "watertight_before": True,
                               "watertight_after": True, "convex_parts": 3})  # fmt: skip
        summaries.append(r / "grasps" / obj / "summary.json")
        write_json(summaries[-1], {
            "object_id": obj, "grasps": 4, "energy_start": {"q50": 900.0}, "energy": q,
            "energy_fell_fraction": 1.0, "terms": {"dis": q, "pen": {"q50": math.nan}},
            "tip_abs_dist": q, "tips_within_5mm_mean": 3.0, "min_candidate_dist": q,
            "max_hand_depth": q, "acceptance_rate": q,
        })  # fmt: skip
        replays.append(_replays(r / "replay" / obj / "replays_0.parquet", obj,
                                [True, True, False, i > 0], [False] * 4))  # fmt: skip
        bench.setdefault("preprocess_object", []).append(
            _bench(r / "benchmarks" / "preprocess_object" / f"{obj}.tsv", 5.0 + i, "200")
        )
        bench.setdefault("anneal_grasps", []).append(
            _bench(r / "benchmarks" / "anneal_grasps" / f"{obj}_shard_0.tsv", 8.0, "300")
        )
        bench.setdefault("replay_grasps", []).append(  # the replay table's wall time
            _bench(r / "benchmarks" / "replay_grasps" / f"{obj}_shard_0.tsv", 37.0 + i, "300")
        )
    write_json(r / "hand" / "hand.json", {
        "joint_names": ["j0", "j1"], "joint_lower": [-0.1, 0.0], "joint_upper": [1.0, 1.5],
        "fingertips": {"index": "tip_i", "thumb": "tip_t"}, "wrist_joint": "wrist",
    })  # fmt: skip
    counts = {s: {"grasps": 0, "stable": 0, "unstable": 0} for s in ("train", "val", "test")}
    objects = {o: {**counts, s: {"grasps": 3, "stable": 50, "unstable": 5 if s != "val" else 0}}
               for o, s in OBJECTS.items()}  # fmt: skip
    dataset = {"window_s": 0.2, "windows": 165, "objects": objects,
               "splits": {s: objects[o][s] for o, s in OBJECTS.items()}}  # fmt: skip
    write_json(r / "datasets" / "baseline" / "summary.json", dataset)
    contact = load_config(REPO / "config", SCHEMA, check_files=False)["replay"]["contact"]
    none = {"n": 0, "q10": None, "q50": None, "q90": None}
    write_json(r / "datasets" / "speeds.json", {
        "contact_model": contact["name"], "contact": contact, "v_slip": 0.0012,
        "box_creep": {"squeeze_n": 5.0, "speed": 0.0071}, "held_creep": {**none, "grasps": 0},
        "target_speed": {"stable": {"n": 3, "q10": 1e-4, "q50": 2e-4, "q90": 5e-4},
                         "unstable": none}, "units": "m/s"})  # fmt: skip
    for ms in (10, 20):
        write_json(r / "datasets" / "sweep" / f"w{ms}ms" / "summary.json",
                   {**dataset, "window_s": ms / 1000})  # fmt: skip
    s = r / "studies"
    paths = []
    for f in FAMILIES:
        for seed in (42, 43):
            paths.append(r / "train" / "baseline" / f / f"seed{seed}" / "metrics.json")
            write_json(paths[-1], _record(f, seed, 0.0, **_motion_records(f, seed)))
    studies.aggregate_baseline(paths, s / "baseline")
    sweep = [_record("lstm", seed, 0.3, window_s=w, test_still=_block(20, 5, 0.3333 + w, 0.6))
             for seed in (42, 43) for w in (0.01, 0.02)]  # fmt: skip
    sweep_runs = aggregate.run_rows(sweep, [{"window_s": x["window_s"]} for x in sweep])
    write_parquet(s / "sweep" / "runs.parquet", sweep_runs)
    write_parquet(s / "sweep" / "summary_defined.parquet",
                  aggregate.seed_summary(sweep_runs, ["family", "window_s", "split"]))
    write_json(s / "sweep" / "threshold_rules.json", aggregate.threshold_rules(sweep_runs))
    # the replay outcome table and the grasp funnel, as their jobs write them
    outcomes = r / "replay" / "outcomes.parquet"
    summarise_replays(replays, outcomes, "gravity")
    funnel_table = r / "report" / "funnel.parquet"
    summarise_funnel(summaries, outcomes, r / "datasets" / "baseline" / "summary.json",
                             funnel_table)  # fmt: skip
    write_json(s / "splits" / "summary.json", {
        "assignments": 2, "defined": 2, "mean": 0.7, "std": 0.1, "median": 0.7, "min": 0.6,
        "fixed_split": 0.8, "hardest": [], "per_assignment": [],
    })  # fmt: skip
    write_json(s / "proxy.json", {"test": {"auprc": 0.55, "auroc": 0.6, "n": 165,
                                           "n_unstable": 10}, **PROXY_STILL})  # fmt: skip
    graph, _ = dag.read_graph(graphs["rulegraph"], graphs["dag"])
    for rule in graph:  # every rule benchmarked, so the stage table has a row for each
        if rule not in bench and rule != "report":
            bench[rule] = [_bench(r / "benchmarks" / rule / "x.tsv", 1.0, "100")]
    config = load_config(REPO / "config", SCHEMA, check_files=False)
    monitor = _monitor_artefacts(r / "monitor", figs)
    anatomy_rows = [{"outcome": "held", "type": None, "onset_s": float("nan"),
                     "still_window": False, "moving_at_settle": False},
                    {"outcome": "failed", "type": "fingertip_slip", "onset_s": 1.5,
                     "still_window": True, "moving_at_settle": False}]  # fmt: skip
    write_json(r / "replay" / "anatomy.json", {"protocol": "gravity", **summarise(anatomy_rows),
                                               "rules": dict(config["labels"]["anatomy"])})
    anatomy = {"reference_summary": r / "replay" / "anatomy.json",
               "reference_figure": _png(r / "figures" / "anatomy.png", 40)}
    return {
        "config": config, "figures": figs, "object_meta": metas,
        "hand_json": r / "hand" / "hand.json", "benchmark_files": bench["preprocess_object"],
        "grasp_summaries": summaries, "anneal_benchmarks": bench["anneal_grasps"],
        "replay_outcomes": outcomes, "funnel": funnel_table,
        "dataset_summary": r / "datasets" / "baseline" / "summary.json",
        "sweep_summaries": sorted(r.glob("datasets/sweep/*/summary.json")),
        "learning": study_artefacts(r), "learning_figures": learning, "rule_benchmarks": bench,
        "rulegraph": graphs["rulegraph"], "jobgraph": graphs["dag"],
        "speeds_summary": r / "datasets" / "speeds.json", "monitor": monitor,
        "anatomy": anatomy,
    }  # fmt: skip


@pytest.fixture(scope="module")
def synthetic_report(
    tmp_path_factory: pytest.TempPathFactory, snakemake_graphs: dict[str, Path]
) -> Path:
    """The real write_report on the synthetic results tree."""
    root = tmp_path_factory.mktemp("report_synthetic")
    write_report(out_html=root / "report.html", **_synthetic_results(root, snakemake_graphs))
    return root / "report.html"


@pytest.fixture(scope="module")
def finished_run_report(run: tuple[Path, dict, list]) -> Path:
    """The report the end-to-end toy run wrote (tests/conftest.py ``run``): the real rule."""
    return run[0] / "results" / "report.html"


@pytest.fixture(
    params=[
        "synthetic_report",
        pytest.param("finished_run_report", marks=pytest.mark.workflow),
    ]
)
def report_html(request: pytest.FixtureRequest) -> Path:
    """Each report in turn (the finished run's only in workflow runs: it needs the toy run)."""
    return request.getfixturevalue(request.param)


def _images(html: str) -> list[bytes]:
    return [base64.b64decode(d) for d in re.findall(r'src="data:image/png;base64,([^"]+)"', html)]


def test_report_has_every_section_and_decodable_images(report_html: Path) -> None:
    html = report_html.read_text()
    ids = re.findall(r'\sid="([^"]+)"', html)
    assert len(ids) == len(set(ids)), "duplicate ids"
    assert set(SECTION_IDS) <= set(ids), sorted(set(SECTION_IDS) - set(ids))
    links = set(re.findall(r'<a href="#([^"]+)"', html))
    assert links <= set(ids) and {"headline", "pipeline", "provenance", "funnel"} <= links
    order = [html.index(f'id="{i}"') for i in ("contents", "headline", "pipeline", "objects")]
    assert order == sorted(order)  # contents, headline and DAG overview come first
    images = _images(html)
    # 8 stage figures + the rule graph (+ 11 learning figures, all present in the synthetic tree),
    # + the monitor's two, + the failure anatomy's, + in the toy run (creep-free enabled) the two
    # speed figures of "Two protocols side by side", the monitor's two under the ramp and the
    # ramp's failure anatomy, + in the toy run the sensor robustness curves
    side_by_side = "This run has no creep-free benchmark" not in html
    assert side_by_side == ('id="protocols-speeds-ramp"' in html)
    assert side_by_side == ('id="monitor-timeline-ramp"' in html)
    sensing = "This run has no sensor-robustness study" not in html
    assert sensing == ('id="sensing-curves"' in html) and 'id="sensing"' in html
    assert side_by_side == ('id="anatomy-figure-creep-free"' in html)
    assert len(images) == 24 + 5 * side_by_side + sensing
    for data in images:
        with Image.open(io.BytesIO(data)) as img:
            img.load()
            assert img.size[0] > 10 and img.size[1] > 10
    assert "issue 4 in progress" not in html
    text = re.sub(r"<[^>]+>", " ", re.sub(r'src="data:[^"]*"', "", html))
    assert not re.search(r"\bnan\b", text, re.IGNORECASE)


def test_synthetic_report_headline_and_provenance(synthetic_report: Path) -> None:
    html = synthetic_report.read_text()
    assert "<b>Quick-profile numbers come from a reduced scale" in html
    assert "12 candidate grasps annealed, 9 usable grasps" in html
    # validation never slips: the tuned-pick row is defined, the proxy's is our number
    assert "<td>55.00 %</td><td>96.27 %</td>" in html
    assert "Stage wall times" in html and "runs now: benchmark after this report" in html
    assert re.search(r"<td>all objects</td><td>12</td><td>12</td><td>0</td><td>8</td>", html)
    # the replay table: 4 simulated seconds per object, its wall time the replay job's
    # benchmark (37 s + i): the replay tables hold no wall time (a measurement, not data)
    for i, obj in enumerate(OBJECTS):
        assert re.search(rf"<td>{obj}</td>(<td>[^<]*</td>){{6}}<td>4</td><td>{37 + i}</td>", html)


def _section(html: str, start: str, end: str) -> str:
    """The HTML between the ids ``start`` and ``end``."""
    return html[html.index(f'id="{start}"') : html.index(f'id="{end}"')]


def _cells(*cells: str) -> str:
    """A regex of consecutive table cells ('*': any cell text)."""
    return "".join("<td>[^<]*</td>" if c == "*" else f"<td>{re.escape(c)}</td>" for c in cells)


def test_synthetic_report_prediction_not_detection(synthetic_report: Path) -> None:
    """The planted still-now numbers in the headline, the benchmark, the sweep and the proxy's
    tables, beside the all-windows ones; an undefined still-now metric prints its reason."""
    html = synthetic_report.read_text()
    head = _section(html, "headline", "pipeline")
    assert "recognising motion already under way" in head and "early warning proper" in head
    never = "undefined: no still-now test window becomes unstable"
    for row in [
        ("CNN (baseline window, mean ± std over seeds)", "AUPRC 98.03 % (one saved checkpoint)",
         "*", "62.00 ± 1.41 %", "*", "72.00 ± 1.41 %", "40", "10", "25.00 %"),
        ("GRU (baseline window, mean ± std over seeds)", "*", "*", never, "*", never, "40", "0",
         "0.00 %"),
        ("LSTM (baseline window, mean ± std over seeds)", "*", "*", "50.00 ± 0.00 %", "*",
         "55.00 ± 0.00 %", "40", "10", "25.00 %"),
        ("friction-ratio proxy", "AUPRC 96.27 %", "55.00 %", "44.44 %", "60.00 %", "55.55 %",
         "40", "10", "25.00 %"),
        ("persistence oracle (reads object motion: a reference line, not a monitor)", "—",
         "77.77 %", "25.00 %", "88.88 %", "50.00 %", "40", "10", "25.00 %"),
    ]:  # fmt: skip
        assert re.search(_cells(*row), head), row
    # the benchmark: test and validation (validation never slips: undefined, with the reason)
    bench = _section(html, "baseline-benchmark", "metrics")
    assert re.search(_cells("test", "CNN", "*", "62.00 ± 1.41 %", "*", "72.00 ± 1.41 %", "40",
                            "10", "25.00 %"), bench)  # fmt: skip
    assert re.search(_cells("validation", "GRU", "*",
                            "undefined: no still-now validation window becomes unstable"), bench)
    sweep = _section(html, "sweep", "latency")
    assert re.search(_cells("10", "LSTM", "*", "34.3 ± 0.0 %", "*", "60.0 ± 0.0 %", "20", "5",
                            "25.0 %"), sweep)  # fmt: skip
    assert re.search(_cells("20", "LSTM", "*", "35.3 ± 0.0 %"), sweep)
    proxy = html[html.index('id="proxy"') : html.index('id="proxy-figure"')]
    assert re.search(_cells("friction-ratio proxy", "55.00 %", "44.44 %", "60.00 %", "55.55 %",
                            "40", "10", "25.00 %"), proxy)  # fmt: skip
    assert re.search(_cells("CNN (mean ± std over seeds)", "*", "62.00 ± 1.41 %"), proxy)
    assert re.search(_cells("GRU (mean ± std over seeds)", "*", never), proxy)
    assert re.search(_cells("persistence oracle (reads object motion)", "77.77 %", "25.00 %",
                            "88.88 %", "50.00 %"), proxy)  # fmt: skip
    for part in (head, bench, sweep, proxy):  # never a 0 for an undefined still-now metric
        assert not re.search(r"<td>0(\.0+)? ?%</td><td>0(\.0+)? ?%</td>", part)


def _without_still_now(kwargs: dict[str, Any]) -> None:
    """Rewrite the studies' artefacts as the code before the still-now metrics wrote them."""
    a = kwargs["learning"]
    for path in (a.baseline_summary_defined, a.baseline_summary, a.sweep_summary_defined,
                 a.baseline_runs, a.sweep_runs):  # fmt: skip
        frame = pl.read_parquet(path)
        write_parquet(path, frame.select(c for c in frame.columns
                                         if not c.startswith(("still_", "moving_"))))
    proxy = read_json(a.proxy)
    write_json(a.proxy, {k: v for k, v in proxy.items() if k not in PROXY_STILL})


def test_synthetic_report_from_artefacts_before_the_still_now_metrics(
    tmp_path: Path, snakemake_graphs: dict[str, Path], synthetic_report: Path
) -> None:
    """Artefacts without the still-now columns and keys: the report renders without the still-now
    parts, and the all-windows tables are exactly those of the report with them."""
    kwargs = _synthetic_results(tmp_path, snakemake_graphs)
    _without_still_now(kwargs)
    write_report(out_html=tmp_path / "report.html", **kwargs)
    old, new = (tmp_path / "report.html").read_text(), synthetic_report.read_text()
    assert "still now" not in old and "still-now" not in old
    assert "still now" in new
    for anchor in ("headline", "baseline-benchmark", "sweep", "proxy"):
        first = [h[h.index(f'id="{anchor}"') :] for h in (old, new)]
        first = [h[: h.index("</table>")] for h in first]
        assert first[0] == first[1], anchor


def test_synthetic_report_under_the_alternative_protocol_options(
    tmp_path: Path, snakemake_graphs: dict[str, Path]
) -> None:
    """The strict model, no squeeze, the `both` reading, and no sensing study or input audit, as
    the report shows them (the toy workflow runs these options through labelling for real)."""
    alternative = {"contact": "strict", "replay": {"squeeze": {"angle": 0.0}},
                   "labels": {"settle": {"require": "both"}}, "sensing": {"robustness": False},
                   "audit": {"enabled": False}}  # fmt: skip
    kwargs = _synthetic_results(tmp_path, snakemake_graphs)
    kwargs["config"] = load_config(REPO / "config", SCHEMA, alternative, check_files=False)
    contact = kwargs["config"]["replay"]["contact"]
    speeds = read_json(kwargs["speeds_summary"])
    write_json(kwargs["speeds_summary"], {**speeds, "contact_model": contact["name"],
                                          "contact": contact})  # fmt: skip
    write_report(out_html=tmp_path / "report.html", **kwargs)
    html = (tmp_path / "report.html").read_text()
    assert "<td>contact model</td><td>strict</td>" in html
    assert "<td>friction cone</td><td>elliptic</td>" in html
    assert "<td>0 (3.2 holds the grasp&#x27;s own angles)</td>" in html
    assert 'id="contact-model"' in html and 'id="unstable-speeds"' in html
    assert "no sensor-robustness study" in html and 'id="sensing-curves"' not in html
    assert "no input audit" in html


# ------------------------------------------------------------------ headless browser


def _chromium() -> tuple[str, str]:
    """Debian's chromium and its matching chromedriver (packages chromium, chromium-driver)."""
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver")
    if not browser or not driver:
        raise FileNotFoundError(
            "headless browser test needs Debian's chromium and chromium-driver: "
            "apt-get install -y chromium chromium-driver (.ci/run installs them)"
        )
    return browser, driver


@pytest.fixture(scope="module")
def browser() -> Any:
    """One headless Chromium for the module, logging every console message."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    binary, driver_path = _chromium()
    options = webdriver.ChromeOptions()
    options.binary_location = binary
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage",
                "--disable-gpu", "--window-size=1280,1000"):  # fmt: skip
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(driver_path), options=options)
    driver.set_page_load_timeout(120)
    yield driver
    driver.quit()


def _render(driver: Any, page: Path) -> dict[str, Any]:
    """Load a page; return its console errors, its images' decode state and a screenshot."""
    driver.get_log("browser")  # drop what an earlier page left
    driver.get(page.resolve().as_uri())
    images = driver.execute_script(
        "return Array.from(document.images).map(i => [i.complete, i.naturalWidth]);"
    )
    errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
    return {"errors": errors, "images": images, "png": driver.get_screenshot_as_png()}


def test_browser_check_catches_errors(browser: Any, tmp_path: Path) -> None:
    """The console check is not vacuous: a missing image and a script error are both caught."""
    page = tmp_path / "broken.html"
    page.write_text('<html><body><h1>x</h1><img src="missing.png">'
                    "<script>undefinedFunction();</script></body></html>")  # fmt: skip
    seen = " ".join(e["message"] for e in _render(browser, page)["errors"])
    assert "missing.png" in seen and "undefinedFunction" in seen


def test_report_renders_in_headless_chromium(browser: Any, report_html: Path) -> None:
    got = _render(browser, report_html)
    assert got["errors"] == [], got["errors"]
    assert got["images"] and all(ok and width > 0 for ok, width in got["images"])
    shot = np.asarray(Image.open(io.BytesIO(got["png"])).convert("L"), dtype=float)
    assert shot.shape[0] > 100 and shot.shape[1] > 100
    assert shot.var() > 0, "blank screenshot"


def test_benchmark_inputs_match_the_dag(snakemake_graphs: dict[str, Path]) -> None:
    """The report's explicit benchmark list names exactly one file per job of the DAG."""
    from graspstab.evaluation.splits import sample_assignments
    from graspstab.report.inputs import benchmark_wildcards

    config = load_config(REPO / "config", SCHEMA, check_files=False)
    splits = {o: e["split"] for o, e in config["objects"]["items"].items()}
    n = len(sample_assignments(splits, config["splits"]["count"], config["splits"]["sample_seed"]))
    wildcards = benchmark_wildcards(config, list(splits), n, FAMILIES)
    counts = dag.job_counts(snakemake_graphs["dag"].read_text())
    expected = {rule: len(values) if isinstance(values, list) else
                math.prod(len(v) for v in values.values())
                for rule, values in wildcards.items()}  # fmt: skip
    assert expected == {rule: counts[rule] for rule in wildcards}
    # the quick profile's validation objects have more shards (synthesis.split_shards)
    per_object = {}
    for combo in wildcards["anneal_grasps"]:
        per_object[combo["object"]] = per_object.get(combo["object"], 0) + 1
    assert {o: n for o, n in per_object.items() if splits[o] == "val"} == {
        "013_apple": 2,
        "010_potted_meat_can": 2,
    }
    assert {n for o, n in per_object.items() if splits[o] != "val"} == {1}


def test_benchmark_inputs_expand_patterns() -> None:
    from graspstab.report.inputs import benchmark_inputs, nested_config_args

    got = benchmark_inputs(
        [("anneal_grasps", "b/anneal_grasps/{object}_shard_{shard}.tsv"),
         ("build_hand", "b/build_hand/hand.tsv"), ("report", "b/report/report.tsv")],
        {"anneal_grasps": {"object": ["x", "y"], "shard": [0, 1]}},
    )  # fmt: skip
    shards = [f"b/anneal_grasps/{o}_shard_{k}.tsv" for o in "xy" for k in (0, 1)]
    explicit = benchmark_inputs(
        [("anneal_grasps", "b/anneal_grasps/{object}_shard_{shard}.tsv")],
        {"anneal_grasps": [{"object": "x", "shard": 0}, {"object": "y", "shard": 2}]},
    )
    assert explicit["benchmark_anneal_grasps"] == [
        "b/anneal_grasps/x_shard_0.tsv",
        "b/anneal_grasps/y_shard_2.tsv",
    ]
    assert got == {
        "benchmark_anneal_grasps": shards,
        "benchmark_build_hand": ["b/build_hand/hand.tsv"],
    }
    with pytest.raises(ValueError, match="new_rule"):
        benchmark_inputs([("new_rule", "b/{k}.tsv")], {})
    args = nested_config_args({"synthesis": {"shards": "3"}, "only_objects": ["a b"], "x": None})
    assert args == '--config \'synthesis={"shards": "3"}\' \'only_objects=["a b"]\' x='
