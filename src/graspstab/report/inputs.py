"""What the report rule asks of the workflow (workflow/rules/report.smk): every other rule's
benchmark files, and the arguments that make a nested Snakemake build this run's DAG. Plain
functions of the workflow's data (no Snakemake import), so they are testable without a workflow.
"""

from __future__ import annotations

import itertools
import json
import shlex
import string
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from graspstab.common.units import ms_of
from graspstab.config import creep_free_seeds, shards_of

REPORT_RULE = "report"


def benchmark_wildcards(
    config: Mapping[str, Any], objects: Sequence[str], assignments: int, models: Sequence[str]
) -> dict[str, dict[str, list] | list[dict[str, Any]]]:
    """Wildcard values, in this run, of every rule whose benchmark path has wildcards. A rule's
    jobs are only known from the DAG, so they are restated here; the report sets these counts
    beside the --dag job counts, where a stale entry shows up as 'DAG: n'. A rule's entry is a
    mapping of value lists (every combination) or a list of explicit combinations."""
    shards = [{"object": o, "shard": k} for o in objects for k in range(shards_of(config, o))]
    sweep = [ms_of(w) for w in config["sweep"]["windows_s"]]
    # trimmed datasets: the sweep's windows plus the tuning and split studies' own
    windows = sorted({*sweep, *(ms_of(config[s]["window_s"]) for s in ("tune", "splits"))})
    objects, models = list(objects), list(models)
    creep_free_sweep = [ms_of(w) for w in config["creep_free"]["sweep_windows_s"]]
    shards_cf = shards if config["creep_free"]["enabled"] else []
    models_cf = models if config["creep_free"]["enabled"] else []
    sensing = config["sensing"]
    augmented = list(sensing["augment"]["families"]) if sensing["robustness"] else []
    augmented_seeds = sensing["augment"]["seeds"] or sensing["seeds"] or config["train"]["seeds"]
    return {
        "fetch_ycb_object": {"object": objects},
        "preprocess_object": {"object": objects},
        "anneal_grasps": shards,
        "summarise_grasps": {"object": objects},
        "replay_grasps": shards,
        "trim_sweep_window": {"ms": windows},
        "train_model": {"model": models, "seed": list(config["train"]["seeds"])},
        "tune_model": {"model": models},
        "export_monitor": {"model": models},
        "train_sweep_model": {"model": models, "ms": sweep, "seed": list(config["sweep"]["seeds"])},
        # the creep-free benchmark's rules (creep_free.smk): no jobs unless it is enabled
        "replay_grasps_creep_free": shards_cf,
        "trim_sweep_window_creep_free": {"ms": creep_free_sweep if models_cf else []},
        "train_model_creep_free": {"model": models_cf, "seed": creep_free_seeds(config, "train")},
        "train_sweep_model_creep_free": {
            "model": models_cf, "ms": creep_free_sweep, "seed": creep_free_seeds(config, "sweep")
        },
        # the sensor-augmented trainings (sensing.smk): none unless the robustness study runs
        "train_augmented_model": {
            "mode": list(sensing["augment"]["modes"]), "model": augmented,
            "seed": list(augmented_seeds),
        },
        # the input audit (audit.smk): none unless it is enabled
        "label_input_set": {"inputs": list(config["audit"]["sets"])
                            if config["audit"]["enabled"] else []},
        "train_input_model": {
            "inputs": list(config["audit"]["sets"]) if config["audit"]["enabled"] else [],
            "model": list(config["audit"]["families"]),
            "seed": list(config["audit"]["seeds"] or config["train"]["seeds"]),
        },
        # the k-fold study (crossval.smk): none unless it is enabled
        **crossval_wildcards(config, objects),
        # the closed loop (closed_loop.smk): none unless it is enabled
        **closed_loop_wildcards(config, objects),
        "train_split_model": {
            "model": [config["splits"]["family"]],
            "k": list(range(assignments)),
            "seed": list(config["splits"]["seeds"]),
        },
    }


def crossval_wildcards(
    config: Mapping[str, Any], objects: Sequence[str]
) -> dict[str, list[dict[str, Any]]]:
    """The k-fold study's training jobs per protocol (crossval.smk's crossval_keys), its folds'
    early-warning jobs, and its per-protocol rules' (no wildcards)."""
    cv = config["crossval"]
    keys: list[dict[str, Any]] = []
    if cv["enabled"]:
        pairs = [("forces", m) for m in cv["families"]] + [
            (v, m) for v in cv["variants"] for m in cv["variant_families"]
        ]
        keys = [{"variant": v, "model": m, "fold": k, "seed": s} for v, m in pairs
                for k in range(cv["k"]) for s in cv["seeds"]]  # fmt: skip
    folds = {"fold": list(range(cv["k"]))}
    warned = [p for p in cv["early_warning"] if p in cv["protocols"]] if cv["enabled"] else []
    return {
        "train_fold_model": keys,
        "train_fold_model_creep_free": keys if "creep_free" in cv["protocols"] else [],
        # the folds' early warning (crossval.early_warning): one job per fold and protocol
        **{"evaluate_fold_monitor" + ("" if p == "reference" else f"_{p}"): folds
           for p in warned},
    }  # fmt: skip


def closed_loop_wildcards(
    config: Mapping[str, Any], objects: Sequence[str]
) -> dict[str, dict[str, list]]:
    """The closed loop's jobs: one per protocol x test object, and one summary per protocol."""
    cl = config["closed_loop"]
    protocols = list(cl["protocols"]) if cl["enabled"] else []
    folds = list(cl["protocols"]) if cl["folds"]["enabled"] else []
    tests = [o for o in objects if config["objects"]["items"][o]["split"] == "test"]
    return {
        "closed_loop_object": {"protocol": protocols, "object": tests},
        "aggregate_closed_loop": {"protocol": protocols},
        "plot_closed_loop": {"protocol": protocols},
        # over the cross-validation folds: every object, each in its own test fold
        "closed_loop_fold_object": {"protocol": folds, "object": list(objects)},
        "closed_loop_fold_offsets": {"protocol": folds if cl["shuffled"] else []},
        "closed_loop_fold_shuffled": {"protocol": folds if cl["shuffled"] else [],
                                      "object": list(objects)},
        "aggregate_closed_loop_folds": {"protocol": folds},
    }


def pattern_fields(pattern: str) -> list[str]:
    """The wildcard names of a path pattern without constraints ("a/{x}_{y}.tsv" -> [x, y])."""
    return list(dict.fromkeys(f for _, f, _, _ in string.Formatter().parse(pattern) if f))


def benchmark_inputs(
    patterns: Iterable[tuple[str, str]], wildcards: Mapping[str, Mapping[str, Sequence]]
) -> dict[str, list[str]]:
    """Named inputs ``benchmark_<rule>`` listing every job's benchmark file of each rule but the
    report (a rule cannot take its own benchmark as input). ``patterns``: (rule, benchmark path
    without wildcard constraints). Explicit paths, not a glob at run time: a glob would miss a job
    that never ran and count files left over from an earlier configuration."""
    out = {}
    for rule, pattern in patterns:
        if rule == REPORT_RULE:
            continue
        fields = pattern_fields(pattern)
        if fields and rule not in wildcards:
            raise ValueError(
                f"rule {rule} has a benchmark with wildcards {fields}: add its wildcard values "
                "to benchmark_wildcards() in src/graspstab/report/inputs.py"
            )
        values = wildcards.get(rule, {})
        if isinstance(values, list):  # explicit combinations (e.g. per-object shard counts)
            combos = [tuple(v[f] for f in fields) for v in values]
        else:
            combos = itertools.product(*(values[f] for f in fields))
        out[f"benchmark_{rule}"] = [
            pattern.format(**dict(zip(fields, combo, strict=True))) for combo in combos
        ]
    return out


def nested_config_args(overrides: Mapping[str, Any]) -> str:
    """A run's raw --config overrides as shell arguments for a nested Snakemake, so that it
    builds the same DAG. Values go as JSON, which Snakemake's YAML parsing reads back unchanged;
    an empty value is how --config spells None."""
    args = [
        f"{k}=" if v is None else f"{k}={json.dumps(v, default=str)}" for k, v in overrides.items()
    ]
    return "--config " + " ".join(shlex.quote(a) for a in args) if args else ""
