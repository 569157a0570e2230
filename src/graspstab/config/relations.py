"""Config checks the schema cannot express: finite numbers, ordered ranges, unique seeds, windows
that name distinct datasets. Each message names the dotted field(s), the value and the fix."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

from graspstab.common.units import ms_of
from graspstab.config.errors import ConfigError

FIX = "Fix it in config/ or in your --config override."


def _leaves(node: Any, path: str = "") -> Iterator[tuple[str, Any]]:
    if isinstance(node, dict):
        for key, value in node.items():
            yield from _leaves(value, f"{path}.{key}" if path else str(key))
    elif isinstance(node, list):
        for i, value in enumerate(node):
            yield from _leaves(value, f"{path}[{i}]")
    else:
        yield path, node


def check_finite(cfg: dict[str, Any]) -> None:
    """Every number is finite: NaN passes every bound (``nan < 0`` and ``nan > 0`` are both
    false), so a NaN threshold would silently label everything one class."""
    bad = [f"{p} = {v}" for p, v in _leaves(cfg) if isinstance(v, float) and not math.isfinite(v)]
    if bad:
        raise ConfigError(f"non-finite numbers in the configuration: {', '.join(bad)}. {FIX}")


def _fail(message: str) -> None:
    raise ConfigError(f"{message} {FIX}")


def _unique(values: list[Any], field: str) -> None:
    dupes = sorted({v for v in values if values.count(v) > 1}, key=str)
    if dupes:
        _fail(f"{field} = {values} repeats {dupes}: each entry must appear once (a repeated seed "
              "would count one run twice in every mean and std).")  # fmt: skip


def check_relations(cfg: dict[str, Any]) -> None:
    """Relations between fields (run after the schema, so every value has its type)."""
    labels = cfg["labels"]
    _check_label_band(labels)
    _check_early_stops(cfg["replay"], labels)
    syn = cfg["synthesis"]
    if syn["seed_block"] is not None and syn["grasps_per_shard"] % syn["seed_block"]:
        _fail(f"synthesis.seed_block = {syn['seed_block']} does not divide "
              f"synthesis.grasps_per_shard = {syn['grasps_per_shard']}: a shard holds whole seed "
              "blocks; choose a divisor, or seed_block: null (each shard one block).")  # fmt: skip
    lo, hi = cfg["synthesis"]["pregrasp"]["standoff"]
    if lo > hi:
        _fail(f"synthesis.pregrasp.standoff = [{lo}, {hi}] is reversed: give [min, max] in metres.")
    ann = cfg["synthesis"]["annealing"]
    if not ann["temperature_start"] > ann["temperature_end"]:
        _fail(f"synthesis.annealing.temperature_start = {ann['temperature_start']} must be above "
              f"temperature_end = {ann['temperature_end']} (3.1.4: T decays from start to end).")
    for group, entries in (cfg["tune"].get("space") or {}).items():
        for name, entry in (entries or {}).items():
            if isinstance(entry, dict) and not entry["low"] <= entry["high"]:
                _fail(f"tune.space.{group}.{name}: low = {entry['low']} is above high = "
                      f"{entry['high']}.")  # fmt: skip
            if isinstance(entry, dict) and entry.get("log") and not entry["low"] > 0:
                _fail(f"tune.space.{group}.{name}: a log range needs low > 0, got {entry['low']}.")
    for field in ("train.seeds", "sweep.seeds", "splits.seeds", "sweep.windows_s"):
        section, key = field.split(".")
        _unique(list(cfg[section][key]), field)
    windows = list(cfg["sweep"]["windows_s"])
    by_ms: dict[int, list[float]] = {}
    for w in windows:
        by_ms.setdefault(ms_of(w), []).append(w)
    for ms, same in sorted(by_ms.items()):
        if ms < 1:
            _fail(f"sweep.windows_s holds {same[0]} s, under one millisecond.")
        if len(same) > 1:
            _fail(f"sweep.windows_s holds {same}, which all round to {ms} ms: the sweep's datasets "
                  "are named in whole milliseconds, so give distinct millisecond lengths.")
    longest = max(windows)
    for field in ("tune.window_s", "splits.window_s"):
        section, key = field.split(".")
        w = cfg[section][key]
        if w > longest:
            _fail(f"{field} = {w} s is longer than the longest sweep window ({longest} s, "
                  "sweep.windows_s): its dataset is trimmed from the sweep's reference dataset, "
                  "so add a window of at least that length to sweep.windows_s or shorten "
                  f"{field}.")  # fmt: skip
    sweep_ms = set(by_ms)
    extra = [w for w in cfg["creep_free"]["sweep_windows_s"] if ms_of(w) not in sweep_ms]
    if extra and cfg["creep_free"]["enabled"]:
        _fail(f"creep_free.sweep_windows_s holds {extra} s, not in sweep.windows_s "
              f"({windows}): the creep-free sweep is set beside the main run's and shares its "
              "latency table, so use windows of the main sweep or add these to sweep.windows_s.")
    _unique(list(cfg["creep_free"]["sweep_windows_s"]), "creep_free.sweep_windows_s")
    _unique(list(cfg["creep_free"]["seeds"] or []), "creep_free.seeds")
    if ms_of(cfg["monitor"]["window_s"]) not in sweep_ms:
        _fail(f"monitor.window_s = {cfg['monitor']['window_s']} s is not a sweep window "
              f"({windows}): the monitor runs the sweep's models at that window, so choose one "
              "of sweep.windows_s or add it there.")  # fmt: skip
    cf_ms = {ms_of(w) for w in cfg["creep_free"]["sweep_windows_s"]}
    _check_crossval(cfg, sweep_ms, cf_ms)
    _check_closed_loop(cfg, sweep_ms, cf_ms)
    if cfg["creep_free"]["enabled"] and ms_of(cfg["monitor"]["window_s"]) not in cf_ms:
        _fail(f"monitor.window_s = {cfg['monitor']['window_s']} s is not among "
              f"creep_free.sweep_windows_s ({list(cfg['creep_free']['sweep_windows_s'])}): the "
              "monitor also runs on the creep-free benchmark's sweep models: add it there.")


def _check_label_band(labels: dict[str, Any]) -> None:
    """3.3.4: r <= label_low is stable, r >= label_high unstable, and the band strictly between
    is ambiguous (dropped). The band must have a width: at label_low == label_high a window with r
    exactly there would be claimed by both classes."""
    low, high = labels["label_low"], labels["label_high"]
    rule = ("(3.3.4: a window is stable when r <= label_low, unstable when r >= label_high, and "
            "dropped as ambiguous between them)")  # fmt: skip
    if low > high:
        _fail(f"labels.label_low = {low} is above labels.label_high = {high}: the band is "
              f"reversed {rule}. Swap the two values (the reference's are label_low: 0.35, "
              "label_high: 0.65).")  # fmt: skip
    if low == high:
        _fail(f"labels.label_low and labels.label_high are both {low}: the ambiguous band "
              f"between them has zero width {rule}, so a window with r = {low} would be both "
              "stable and unstable. label_low must be below label_high: lower label_low or raise "
              "label_high to give the band a width (the reference's: 0.35 and 0.65).")


def _check_closed_loop_folds(cfg: dict[str, Any]) -> None:
    """The closed loop over the folds has folds, each protocol's budget thresholds, fold models
    at its window, and no pick (an export of the fixed split)."""
    cl, cv = cfg["closed_loop"], cfg["crossval"]
    if not cl["folds"]["enabled"]:
        return
    if not cv["enabled"]:
        _fail("closed_loop.folds.enabled needs the cross-validation: turn it on with "
              "--config crossval=kfold (the wide profile does), or turn the folds off.")
    missing = [p for p in cl["protocols"]
               if p not in cv["protocols"] or p not in cv["early_warning"]]  # fmt: skip
    if missing:
        _fail(f"closed_loop.folds.enabled runs closed_loop.protocols = {list(cl['protocols'])}, "
              f"but {missing} are not in both crossval.protocols = {list(cv['protocols'])} and "
              f"crossval.early_warning = {list(cv['early_warning'])}, which give each fold its "
              "models and budget thresholds: add them there, or drop them from "
              "closed_loop.protocols.")  # fmt: skip
    if "pick" in cl["policies"]:
        _fail("closed_loop.folds.enabled: the pick is an export of the fixed split's sweep and "
              "has no fold model; drop it from closed_loop.policies.")
    if ms_of(cl["window_s"]) != ms_of(cv["window_s"]):
        _fail(f"closed_loop.folds.enabled: closed_loop.window_s = {cl['window_s']} s is not "
              f"crossval.window_s = {cv['window_s']} s, the folds' models' window; set both alike.")


def _check_closed_loop(cfg: dict[str, Any], sweep_ms: set[int], cf_ms: set[int]) -> None:
    """The closed loop's monitors exist: the creep-free protocol has its benchmark, and a policy
    driven by a sweep model or the proxy runs at a sweep window of each protocol it runs under."""
    cl = cfg["closed_loop"]
    _check_closed_loop_folds(cfg)
    if not cl["enabled"]:
        return
    if "creep_free" in cl["protocols"] and not cfg["creep_free"]["enabled"]:
        _fail(f"closed_loop.protocols = {list(cl['protocols'])} names creep_free but "
              "creep_free.enabled is false: the creep-free protocol's monitors are the creep-free "
              "benchmark's sweep models. To fix it, set creep_free.enabled=true, or "
              "closed_loop.protocols=[reference]: --config 'creep_free={enabled: true}' (the "
              "closed_loop profile does), or --config 'closed_loop={enabled: true, protocols: "
              "[reference]}'.")  # fmt: skip
    windowed = {"proxy", "cnn", "gru", "lstm"}
    if not windowed & {*cl["policies"], *cl["sweep"]["policies"]}:
        return
    w = cl["window_s"]
    if ms_of(w) not in sweep_ms:
        _fail(f"closed_loop.window_s = {w} s is not a sweep window "
              f"({list(cfg['sweep']['windows_s'])}): the closed loop's monitors are the sweep's "
              "models and the proxy on the sweep's dataset at that window; choose one of "
              "sweep.windows_s or add it there.")  # fmt: skip
    if "creep_free" in cl["protocols"] and ms_of(w) not in cf_ms:
        _fail(f"closed_loop.window_s = {w} s is not among creep_free.sweep_windows_s "
              f"({list(cfg['creep_free']['sweep_windows_s'])}): the creep-free protocol's "
              "monitors are that benchmark's sweep models; add it there, or run the reference "
              "protocol only (closed_loop.protocols: [reference]).")  # fmt: skip
    if "budget" in cl["thresholds"] and ms_of(w) != ms_of(cfg["monitor"]["window_s"]):
        _fail(f"closed_loop.thresholds holds budget but closed_loop.window_s = {w} s is not "
              f"monitor.window_s = {cfg['monitor']['window_s']} s: the budget thresholds are the "
              "grasp-level evaluation's, chosen for the models at monitor.window_s. Set both "
              "windows alike, or drop budget (--config 'overrides=[\"closed_loop.thresholds="
              "[recall]\"]').")  # fmt: skip


def _check_crossval(cfg: dict[str, Any], sweep_ms: set[int], cf_ms: set[int]) -> None:
    """The k-fold study's folds fit the objects, its window is a sweep dataset, and the
    creep-free protocol has its benchmark."""
    cv = cfg["crossval"]
    if not cv["enabled"]:
        return
    _unique(list(cv["seeds"]), "crossval.seeds")
    n = len(cfg["only_objects"] or cfg["objects"]["items"])
    if cv["k"] > n:
        _fail(f"crossval.k = {cv['k']} folds but the run has {n} objects: every fold needs a "
              f"test object, so choose k <= {n}.")  # fmt: skip
    if cv["val_folds"] > cv["k"] - 2:
        _fail(f"crossval.val_folds = {cv['val_folds']} leaves no training fold with k = "
              f"{cv['k']}: choose val_folds <= {cv['k'] - 2}.")  # fmt: skip
    if ms_of(cv["window_s"]) not in sweep_ms:
        _fail(f"crossval.window_s = {cv['window_s']} s is not a sweep window "
              f"({list(cfg['sweep']['windows_s'])}): the study trains on the sweep's same-end "
              "dataset at that window; choose one of sweep.windows_s or add it there.")
    if "creep_free" in cv["protocols"]:
        if not cfg["creep_free"]["enabled"]:
            _fail("crossval.protocols holds creep_free but creep_free.enabled is false: turn the "
                  "benchmark on (--config 'creep_free={enabled: true}'; crossval=kfold does) or "
                  "drop the protocol (--config 'overrides=[\"crossval.protocols=[reference]\"]').")
        if ms_of(cv["window_s"]) not in cf_ms:
            _fail(f"crossval.window_s = {cv['window_s']} s is not among "
                  f"creep_free.sweep_windows_s ({list(cfg['creep_free']['sweep_windows_s'])}): "
                  "add it there for the creep-free protocol.")


def _check_early_stops(replay: dict[str, Any], labels: dict[str, Any]) -> None:
    """The replay's early stops must never cut a trace the labelling stage would still use: the
    contact-loss stop waits at least as long as the contact-end rule, and the depth stop is at
    least as strict as the depth rule and starts no earlier than the settle search ends."""
    if replay["stop_after_loss_s"] < labels["contact_loss_s"]:
        _fail(f"replay.stop_after_loss_s = {replay['stop_after_loss_s']} s is shorter than "
              f"labels.contact_loss_s = {labels['contact_loss_s']} s: a replay would stop before "
              "the labelling stage can see that contact ended, so raise stop_after_loss_s.")
    deep, settle = replay["deep_stop"], labels["settle"]
    if not deep["enabled"]:
        return
    looser = [
        f"{mine} = {deep[key]} against labels.settle.{theirs} = {settle[theirs]}"
        for key, mine, theirs, ok in (
            ("depth", "replay.deep_stop.depth", "penetration_reject",
             deep["depth"] <= settle["penetration_reject"]),
            ("seconds", "replay.deep_stop.seconds", "penetration_reject_s",
             deep["seconds"] >= settle["penetration_reject_s"]),
            ("after_s", "replay.deep_stop.after_s", "search_s",
             deep["after_s"] >= settle["search_s"]),
        )
        if not ok
    ]  # fmt: skip
    if looser:
        _fail(f"the replay's depth stop would cut replays the depth rule (3.3.1) keeps: "
              f"{'; '.join(looser)}. It must be at least as deep, as long and as late; set the "
              "replay.deep_stop values to the labels.settle ones, or replay.deep_stop.enabled: "
              "false to replay in full.")  # fmt: skip
