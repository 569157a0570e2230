"""The closed loop's policies built from a run's files: each family's model, the pick, the proxy.

Every monitor keeps its validation-selected threshold (the learning stage's for a model, the
proxy's own on the validation windows) and carries its measured per-score latency from the
latency study (4.5: batch-1 CPU forward pass, median), which the reflex adds to its delay. The
proxy's latency is taken as zero: it is one division per fingertip.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import polars as pl

from graspstab.closedloop.policies import BUDGET, BUDGETED, FIXED, SHUFFLED, Policy, oracle_name
from graspstab.common.io import read_parquet
from graspstab.monitor.checkpoint import read_trained
from graspstab.monitor.export import load_onnx
from graspstab.monitor.proxy import proxy_scorer
from graspstab.monitor.scoring import TorchScorer


def latency_s(table: str | Path, family: str, window_steps: int) -> float:
    """The median batch-1 latency [s] of ``family`` at ``window_steps`` in the latency study's
    table (any study's row with that family and window), or an error naming what is missing."""
    rows = read_parquet(table).filter((pl.col("family") == family)
                                      & (pl.col("window_steps") == window_steps))  # fmt: skip
    if rows.height == 0:
        raise ValueError(f"{table}: no latency row for family {family!r} at {window_steps} "
                         "steps; closed_loop.window_s must be a sweep window")  # fmt: skip
    return float(rows["median_ms"].median()) / 1e3


def build_policies(
    names: list[str],
    *,
    checkpoints: Mapping[str, tuple[str | Path, str | Path]] | None = None,
    pick_onnx: str | Path | None = None,
    proxy_dataset: str | Path | None = None,
    threshold: Mapping[str, Any] | None = None,
    latency_table: str | Path | None = None,
    oracle_leads_s: list[float] | None = None,
    shuffled: bool = False,
    thresholds: tuple[str, ...] | list[str] = ("recall",),
    budget: Mapping[str, Mapping[str, Any]] | None = None,
) -> list[Policy]:
    """The policies ``names`` (``closed_loop.policies``), in the order of
    ``policies.policy_names``: fixed ones need nothing (``oracle`` is one policy per lead of
    ``oracle_leads_s``); a family needs its (checkpoint, metrics.json) in ``checkpoints``;
    ``pick`` its exported ONNX file; ``proxy`` the dataset whose validation windows set its
    threshold by the train group's ``threshold`` rule. Models' latencies come from
    ``latency_table``. Each monitor runs at each of ``thresholds``: ``recall`` (its own
    validation-selected threshold, the reference's rule) and ``budget`` (``<name>-budget``: the
    grasp-level evaluation's threshold for the false-warning budget, ``budget``: the
    ``early_warning.monitors`` of its summary; a threshold at the grid floor is kept, flagged).
    With ``shuffled``, each monitor's shuffled-timing control follows."""
    base = _base_policies(names, checkpoints=checkpoints, pick_onnx=pick_onnx,
                          proxy_dataset=proxy_dataset, threshold=threshold,
                          latency_table=latency_table, oracle_leads_s=oracle_leads_s)  # fmt: skip
    choices = None if budget is None else {n: b["threshold"] for n, b in budget.items()}
    return with_thresholds(base, thresholds, choices, shuffled)


def with_thresholds(policies: list[Policy], thresholds: tuple[str, ...] | list[str],
                    budget: Mapping[str, Mapping[str, Any]] | None,
                    shuffled: bool) -> list[Policy]:  # fmt: skip
    """Each monitor of ``policies`` at each of ``thresholds`` (``recall``: as it is; ``budget``:
    ``<name>-budget`` at ``budget[name]``, a ``budget_threshold`` choice, flagged when at the
    grid floor or above every score), then with ``shuffled`` each monitor's shuffled control."""
    out: list[Policy] = []
    for policy in policies:
        if policy.kind != "monitor":
            out.append(policy)
            continue
        if "recall" in thresholds:
            out.append(policy)
        if "budget" in thresholds and policy.name in BUDGETED:
            if budget is None or policy.name not in budget:
                raise ValueError(f"closed loop: no budget threshold for {policy.name!r} (the "
                                 "grasp-level evaluation's early_warning, or the fold's "
                                 "thresholds.json)")  # fmt: skip
            c = budget[policy.name]
            out.append(dataclasses.replace(
                policy, name=f"{policy.name}{BUDGET}", threshold=float(c["threshold"]),
                at_floor=bool(c["at_floor"]), never_warns=bool(c.get("never_warns"))))
    if shuffled:
        out += [Policy(f"{p.name}{SHUFFLED}", "shuffled", of=p.name)
                for p in list(out) if p.kind == "monitor"]  # fmt: skip
    return out


def _base_policies(names: list[str], *, checkpoints: Any, pick_onnx: Any, proxy_dataset: Any,
                   threshold: Any, latency_table: Any, oracle_leads_s: list[float] | None,
                   proxy_val: list[str] | None = None) -> list[Policy]:  # fmt: skip
    """Each named policy once, a monitor at its own validation-selected threshold (the proxy's
    on the dataset's validation windows, or on ``proxy_val``'s objects' windows)."""
    out = []
    for name in names:
        if name == "oracle" and oracle_leads_s:
            out += [Policy(oracle_name(x), "oracle", lead_s=float(x)) for x in oracle_leads_s]
        elif name in FIXED:
            out.append(Policy(name, name))
        elif name == "proxy":
            scorer, _ = proxy_scorer(proxy_dataset, threshold, proxy_val)
            out.append(Policy(name, "monitor", scorer, scorer.constants.threshold, 0.0))
        elif name == "pick":
            scorer = load_onnx(pick_onnx)
            c = scorer.constants
            out.append(Policy(name, "monitor", scorer, c.threshold,
                              latency_s(latency_table, c.family, c.window_steps)))  # fmt: skip
        else:
            model, constants = read_trained(*checkpoints[name])
            out.append(Policy(name, "monitor", TorchScorer(model, constants), constants.threshold,
                              latency_s(latency_table, name, constants.window_steps)))  # fmt: skip
    return out


def build_fold_policies(
    names: list[str],
    *,
    checkpoints: Mapping[str, tuple[str | Path, str | Path]],
    fold_thresholds: Mapping[str, Any],
    proxy_dataset: str | Path | None,
    assignment: Mapping[str, str],
    threshold: Mapping[str, Any],
    latency_table: str | Path,
    oracle_leads_s: list[float] | None = None,
    shuffled: bool = False,
    thresholds: tuple[str, ...] | list[str] = ("recall",),
) -> list[Policy]:
    """The policies of one cross-validation fold's closed loop, as :func:`build_policies` gives
    them on the fixed split, from the fold's own files: each family's fold model (its
    validation-selected threshold), the proxy with its threshold on the fold's validation
    windows, and the budget thresholds ``evaluate_fold_monitor`` chose on the fold's validation
    grasps (``fold_thresholds``: its thresholds.json). The pick has no fold model: refused."""
    if "pick" in names:
        raise ValueError("closed loop over the folds: the pick is an export of the fixed split's "
                         "sweep and has no fold model; leave it out of closed_loop.policies")
    out = _base_policies(names, checkpoints=checkpoints, pick_onnx=None,
                         proxy_dataset=proxy_dataset, threshold=threshold,
                         latency_table=latency_table, oracle_leads_s=oracle_leads_s,
                         proxy_val=[o for o, s in assignment.items() if s == "val"])  # fmt: skip
    return with_thresholds(out, thresholds, fold_thresholds["thresholds"], shuffled)
