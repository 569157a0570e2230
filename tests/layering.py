"""The library's layering, declared once: one sub-package of ``src/graspstab`` per pipeline stage,
in floors, each with the packages it may import and the stage entry modules the workflow scripts
run. ``tests/test_layering.py`` checks the source against this declaration, and the stage table of
docs/design.md ("Stages, in order") is generated from it:

    python -m tests.layering           # print the table
    python -m tests.layering --write   # replace it in docs/design.md, between the markers

A package may import itself and the packages in its ``may_import`` (all on lower floors), nothing
else; ``common`` is the floor under everything. A stage entry module (:data:`ENTRY_MODULES`) holds
the function a workflow script runs as a job's work: only the workflow scripts and the modules of
its own package import it, the other stages import the library modules beside it.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DESIGN = REPO / "docs" / "design.md"
TABLE_START = "<!-- stages-table:start -->"
TABLE_END = "<!-- stages-table:end -->"


@dataclass(frozen=True)
class Stage:
    package: str  # the sub-package of graspstab
    job: str  # one line, for the docs table
    reads: str
    writes: str
    may_import: frozenset[str]  # other packages it may import; each on a lower floor
    # the only modules of this package that other packages may import (None: any module)
    public: frozenset[str] | None = None


def _stage(package: str, job: str, reads: str, writes: str, may_import: str = "",
           public: str | None = None) -> Stage:  # fmt: skip
    return Stage(package, job, reads, writes, frozenset(may_import.split()),
                 None if public is None else frozenset(public.split()))  # fmt: skip


# The floors, lowest first. ``may_import`` is the minimal set the source needs today; adding to it
# is a design decision (and a package on a higher floor is never allowed).
STAGES: tuple[Stage, ...] = (
    _stage(
        "common",
        "atomic output, the artefact readers, provenance, the result cache, logging, the jobs' "
        "error handling",
        "-",
        "-",
    ),
    _stage(
        "metrics",
        "scores of a binary classifier on windows and the decision threshold's choice: the one "
        "definition that training and every evaluation use (3.5.3, 4.2, 4.6)",
        "-",
        "- (a library)",
        "common",
    ),
    _stage(
        "assets",
        "obtain and checksum inputs: YCB meshes, the ORCA v2 description",
        "local copies or pinned downloads",
        "`resources/`",
        "common",
    ),
    _stage(
        "config",
        "compose the Hydra tree once, validate it (object ids against the asset catalogue), hand "
        "out slices; the configuration page's generator",
        "`config/`, the schema",
        "-",
        "common assets",
    ),
    _stage(
        "objects",
        "repair, upright frame, centre of mass, inertia, CoACD parts, SDF grid, hull samples "
        "(3.1.1)",
        "one mesh",
        "`results/objects/<id>/`",
        "common assets",
    ),
    _stage(
        "hand",
        "the hand MJCF without tower/forearm, capsules, contact candidates (3.1.2)",
        "the description",
        "`results/hand/`",
        "common",
    ),
    _stage(
        "synthesis",
        "pre-grasps and batched simulated annealing of eq. 4 (3.1.3-3.1.4)",
        "object + hand",
        "`results/grasps/<id>/shard_<k>.parquet`",
        "common objects hand",
    ),
    _stage(
        "replay",
        "hold each grasp under gravity, record traces (3.2); the per-grasp settings "
        "(`replay/grasp_setup.py`), the trace layout (`replay/traces.py`), how each protocol's "
        "replays ended (`replay/outcomes.py`)",
        "grasps + object + hand",
        "`results/replay/<id>/traces_<k>.npz`, `replays_<k>.parquet`, "
        "`results/replay/outcomes.parquet`",
        "common hand",
    ),
    _stage(
        "labels",
        "usable interval, eq. 23 labels and the other label sources (`labels/sources.py`), the "
        "usable replays (`labels/replays.py`), windows, datasets and their format "
        "(`labels/dataset.py`), same-end trims, the input sets, the grasp funnel, the failure "
        "anatomy (3.3, 3.5.4)",
        "replays, grasp summaries",
        "`results/datasets/...`, `results/report/funnel.parquet`, "
        "`results/replay/anatomy.{parquet,json}`",
        "common hand replay",
    ),
    _stage(
        "sensing",
        "the sensor model (delay, gain, drift, noise, quantisation, rate with a hold, drops), its "
        "conditions, and force segments with context before each window",
        "windows' traces",
        "- (a library the learning and evaluation stages apply)",
        "common labels",
    ),
    _stage(
        "learning",
        "models, the training loop (optionally through the sensors), one model x dataset x seed "
        "with its best epoch and threshold chosen on validation and its held-out scores, Optuna "
        "tuning (3.4-3.5, 4.1)",
        "datasets",
        "`results/train/.../predictions.parquet`, `model.pt`; `results/tune/`",
        "common metrics labels sensing",
    ),
    _stage(
        "evaluation",
        "what the models and reference scorers are worth, never training itself: each run's test "
        "once (`tested_run`: validation and test metrics, pooled and per object), multi-seed study "
        "tables, split assignments and k-fold folds with bootstrap intervals, latency, the "
        "friction-ratio proxy, sensor robustness (3.5.4, 4.2-4.7)",
        "training runs (predictions, checkpoints), datasets",
        "`results/train/.../metrics.json`, `results/studies/`",
        "common metrics labels sensing learning",
    ),
    _stage(
        "figures",
        "the chapter-4 figures (4.1-4.10, the Optuna histories, k-fold, sensor robustness) and how "
        "the learning results are named and shown: `presentation` and `artefacts` load no "
        "matplotlib and are the only modules other packages import",
        "the studies' tables, training runs, tuning trials",
        "`results/figures/learning/`, `results/figures/crossval/`, `results/figures/sensing/`",
        "common metrics evaluation",
        public="presentation artefacts",
    ),
    _stage(
        "monitor",
        "streaming monitor (ring buffer, stride, debounce), TorchScript/ONNX export, grasp-level "
        "evaluation of each family and the proxy over the held-out replays",
        "checkpoints and their metrics, the held-out replays, a sweep dataset",
        "`results/monitor/` (exports, `episodes.parquet`, `summary.json`, `timeline.npz`), "
        "`results/figures/monitor/`",
        "common metrics hand labels learning evaluation",
    ),
    _stage(
        "closedloop",
        "the grip reflex: the streaming monitor in the replay's loop, tightening the closing "
        "joints when it warns (a controller the replay runs between chunks)",
        "exports, grasps, objects, hand",
        "`results/closed_loop/<protocol>/<object>.parquet` (one row per grasp and policy), "
        "`results/closed_loop/summary/<protocol>/` (per policy, bootstrap intervals, comparisons, "
        "worse grasps)",
        "common replay labels monitor",
    ),
    _stage(
        "report",
        "the HTML report and its headline table",
        "every stage's outputs, as declared inputs",
        "`results/report.html`",
        "common config figures",
    ),
)

BY_PACKAGE: dict[str, Stage] = {s.package: s for s in STAGES}
FLOOR: dict[str, int] = {s.package: i for i, s in enumerate(STAGES)}

# The stage entry modules: each holds the function a workflow script runs as a job's work
# (workflow/scripts/*.py). The library helpers a script also imports (common.cache, common.jobs,
# learning.specs, replay.traces, labels.trace_windows, closedloop.sources, figures.artefacts, ...)
# are not entry modules.
ENTRY_MODULES: frozenset[str] = frozenset({
    "graspstab.assets.hand",                 # fetch_hand_description
    "graspstab.assets.ycb",                  # fetch_ycb_object
    "graspstab.objects.preprocess_object",   # preprocess_object
    "graspstab.objects.figure",              # plot_objects
    "graspstab.hand.build_hand",             # build_hand
    "graspstab.hand.figure",                 # plot_hand
    "graspstab.synthesis.anneal_grasps",     # anneal_grasps
    "graspstab.synthesis.summarise_grasps",  # summarise_grasps
    "graspstab.synthesis.plot_grasps",       # plot_grasps
    "graspstab.replay.replay_grasps",        # replay_grasps
    "graspstab.replay.outcomes",             # summarise_replays
    "graspstab.labels.build_datasets",       # label_windows, trim_sweep_window
    "graspstab.labels.funnel",               # summarise_funnel
    "graspstab.labels.summarise_anatomy",    # summarise_anatomy
    "graspstab.labels.input_sets",           # label_input_set
    "graspstab.labels.figure",               # plot_replay, plot_window
    "graspstab.labels.speed_figure",         # plot_unstable_speeds
    "graspstab.evaluation.tested_run",       # train_model (train, then test once)
    "graspstab.learning.tune_model",         # tune_model
    "graspstab.evaluation.studies",          # aggregate_*, measure_latency, evaluate_proxy
    "graspstab.evaluation.robustness",       # evaluate_sensor_robustness
    "graspstab.figures.entry",               # plot_learning
    "graspstab.figures.crossval",            # plot_crossval
    "graspstab.figures.robustness",          # plot_sensor_robustness
    "graspstab.monitor.evaluate_monitor",    # evaluate_monitor
    "graspstab.monitor.evaluate_fold_monitor",  # evaluate_fold_monitor*
    "graspstab.monitor.aggregate_fold_warning",  # aggregate_fold_warning*
    "graspstab.monitor.export_models",       # export_monitor
    "graspstab.monitor.figures",             # plot_monitor
    "graspstab.closedloop.closed_loop",      # closed_loop_object
    "graspstab.closedloop.summary",          # aggregate_closed_loop
    "graspstab.closedloop.figures",          # plot_closed_loop
    "graspstab.report.write_report",         # write_report
})  # fmt: skip

# Workflow scripts that run no stage entry module, with the reason (none today).
SCRIPTS_WITHOUT_ENTRY: dict[str, str] = {}

# Imports of another stage's entry module that are known and not yet moved, with what to do:
# (module path under src/graspstab, entry module) -> reason. The test fails on any other such
# import, and on an entry here that no longer occurs (so it is removed once fixed).
KNOWN_ENTRY_IMPORTS: dict[tuple[str, str], str] = {}


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def render_table() -> str:
    """The markdown table of docs/design.md's "Stages, in order", one row per floor."""
    rows = ["| # | package | job | reads | writes |", "|---|---|---|---|---|"]
    rows += [f"| {i} | `{s.package}` | {_cell(s.job)} | {_cell(s.reads)} | {_cell(s.writes)} |"
             for i, s in enumerate(STAGES)]  # fmt: skip
    return "\n".join(rows) + "\n"


def table_in(text: str) -> str | None:
    """The text between the table's markers in ``text`` (None unless exactly one pair, in
    order)."""
    if text.count(TABLE_START) != 1 or text.count(TABLE_END) != 1:
        return None
    head, _, rest = text.partition(TABLE_START)
    inner, _, _ = rest.partition(TABLE_END)
    return None if TABLE_END in head else inner


def with_table(text: str) -> str:
    """``text`` with the generated table between its markers."""
    if table_in(text) is None:
        raise SystemExit(f"{DESIGN}: expected one {TABLE_START} ... {TABLE_END} pair")
    head, _, rest = text.partition(TABLE_START)
    _, _, tail = rest.partition(TABLE_END)
    return f"{head}{TABLE_START}\n\n{render_table()}\n{TABLE_END}{tail}"


def main(argv: list[str]) -> int:
    if argv == ["--write"]:
        DESIGN.write_text(with_table(DESIGN.read_text()))
        print(f"wrote the stage table into {DESIGN.relative_to(REPO)}")
    elif not argv:
        print(render_table(), end="")
    else:
        print("usage: python -m tests.layering [--write]", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
