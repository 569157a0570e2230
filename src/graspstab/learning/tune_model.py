"""Optuna tuning of one model family (thesis 4.1.2, table 4.1): seeded TPE with median pruning.

The study lives in an Optuna storage (SQLite beside the results by default, any database URL
Optuna accepts otherwise) under a name derived from the tuning parameters, so a killed run resumes
where it stopped (its interrupted trial is marked failed and not counted) and a changed search
space starts a fresh study instead of mixing trials. Workers sharing a database study count each
other's live trials (graspstab.learning.storage), so together they finish exactly ``trials``. The
best configuration is written out as a complete model spec that the sweep and split studies train
with.
"""

from __future__ import annotations

import logging
import math
import time
import zlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import optuna
import polars as pl
import torch

from graspstab.common.io import write_json, write_parquet
from graspstab.common.logs import setup_logging
from graspstab.common.provenance import code_version, compute_platform, stable_hash
from graspstab.learning.data import load_window_data
from graspstab.learning.models import build_model
from graspstab.learning.storage import hide_password, live_trials, open_storage
from graspstab.learning.train import TrainSettings, fit

log = logging.getLogger("graspstab.learning")

# Settings that only change the decision threshold, not the ranking the objective measures.
THRESHOLD_KEYS = ("threshold_rule", "min_recall")
RECURRENT = ("gru", "lstm")
# How often a worker whose remaining trials run elsewhere looks whether they have finished [s].
WAIT_S = 2.0


class SurplusTrial(Exception):
    """A trial started concurrently with another that already makes ``trials``: failed unrun."""


def search_space(space: Mapping[str, Any], family: str, objective: str) -> dict[str, Any]:
    """The parameters searched for one family: the common group plus the family's group
    (``cnn`` or ``recurrent``). Threshold settings are searched only for a threshold-dependent
    objective (F1): with AUPRC they cannot change the trial's value, so sampling them would only
    hand the sweep a random threshold rule."""
    group = "recurrent" if family in RECURRENT else family
    out = dict(space.get("common", {}))
    out.update(space.get(group, {}))
    if objective != "f1":
        for key in THRESHOLD_KEYS:
            out.pop(key, None)
    return out


def suggest(trial: optuna.Trial, name: str, spec: Any) -> Any:
    """One suggestion: a list is categorical; {low, high[, log]} is a float (int when both
    bounds are integers) range."""
    if isinstance(spec, list):
        return trial.suggest_categorical(name, spec)
    if isinstance(spec, Mapping) and {"low", "high"} <= set(spec):
        low, high, use_log = spec["low"], spec["high"], bool(spec.get("log", False))
        if isinstance(low, int) and isinstance(high, int):
            return trial.suggest_int(name, low, high, log=use_log)
        return trial.suggest_float(name, float(low), float(high), log=use_log)
    raise ValueError(
        f"tune.space: {name!r} must be a list (categorical) or a mapping with low/high, "
        f"got {spec!r}"
    )


def sampler_seed(seed: int, family: str) -> int:
    """The family's own TPE stream (SeedSequence of seed and family): GRU and LSTM share a
    search space, and one stream would propose them identical trials."""
    return int(np.random.SeedSequence([seed, zlib.crc32(family.encode())]).generate_state(1)[0])


def storage_url(storage: str | None, default_path: Path, family: str) -> str:
    """The storage URL: ``storage`` (``{model}`` replaced by the family) or SQLite at
    ``default_path``."""
    if storage:
        return storage.replace("{model}", family)
    default_path.parent.mkdir(parents=True, exist_ok=True)
    return f"sqlite:///{default_path.resolve()}"


def _objective_value(row: Mapping[str, float], objective: str) -> float:
    """The trial value of one epoch's validation row (higher is better)."""
    if objective == "loss":
        return -row["val_loss"]
    return row[f"val_{objective}"]


def tune_model(
    dataset_dir: str | Path,
    base_spec: Mapping[str, Any],
    train: Mapping[str, Any],
    tune: Mapping[str, Any],
    out_best: str | Path,
    out_trials: str | Path,
    *,
    default_storage: str | Path,
    threads: int = 1,
    log_file: str | Path | None = None,
) -> dict[str, Any]:
    """Run (or resume) the family's study until it holds ``tune.trials`` finished trials."""
    setup_logging(log_file)
    optuna.logging.enable_propagation()
    optuna.logging.disable_default_handler()
    torch.set_num_threads(max(1, int(threads)))
    family = base_spec["family"]
    data = load_window_data(dataset_dir)
    stable, unstable = data.class_counts("val")
    objective = tune["objective"]
    if objective != "loss" and (stable == 0 or unstable == 0):
        log.warning(
            "validation has %d stable / %d unstable windows: %s undefined, tuning on validation "
            "loss instead", stable, unstable, objective,
        )  # fmt: skip
        objective = "loss"
    space = search_space(tune["space"], family, objective)
    # Recorded in best.json: the storage URL without its password.
    shown = {**tune, "storage": hide_password(tune["storage"])} if tune.get("storage") else tune
    params = {"base": dict(base_spec), "train": dict(train), "tune": dict(shown),
              "dataset": str(dataset_dir), "objective": objective}  # fmt: skip
    # The study's identity: what defines its trials (not how many are wanted, nor where stored),
    # so raising ``trials`` resumes the same study.
    identity = {**params, "tune": {k: v for k, v in tune.items() if k not in ("trials", "storage")}}
    study_name = f"{family}-{stable_hash(identity, 12)}"
    url = storage_url(tune.get("storage"), Path(default_storage), family)
    sampler = optuna.samplers.TPESampler(seed=sampler_seed(int(tune["seed"]), family))
    pruner = optuna.pruners.MedianPruner(
        n_startup_trials=int(tune["pruner"]["startup_trials"]),
        n_warmup_steps=int(tune["pruner"]["warmup_epochs"]),
    )
    shared = bool(tune.get("storage"))
    # A configured database may be shared by several workers: their interrupted trials are found
    # by heartbeat. The default SQLite file belongs to this job alone, so any RUNNING trial in it
    # was interrupted by a kill and is failed at once.
    storage = open_storage(url, shared=shared)
    study = optuna.create_study(
        study_name=study_name, storage=storage, sampler=sampler, pruner=pruner,
        direction="maximize", load_if_exists=True,
    )  # fmt: skip
    done_states = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)
    if not shared:
        for t in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,)):
            study._storage.set_trial_state_values(t._trial_id, optuna.trial.TrialState.FAIL)
            log.info("trial %d was interrupted in an earlier run: marked failed", t.number)
    target = int(tune["trials"])

    def progress() -> tuple[int, set[int]]:
        """Finished trials, and the numbers of the live running ones: other workers' (this
        one runs none when it asks), plus its own inside ``run_trial``."""
        finished = len(study.get_trials(deepcopy=False, states=done_states))
        return finished, live_trials(storage, study._study_id)

    finished, live = progress()
    log.info("study %s at %s: %d finished trials, %d running elsewhere, running %d more",
             study_name, url.split("://")[0], finished, len(live),
             max(0, target - finished - len(live)))  # fmt: skip

    def run_trial(trial: optuna.Trial) -> float:
        # Two workers that asked at once may both have started a trial the study needs only one
        # of: the one numbered later yields, before training.
        finished, live = progress()
        if finished + len({n for n in live if n < trial.number}) >= target:
            study.stop()
            raise SurplusTrial(f"trial {trial.number} not run: the study already holds {target} "
                               "finished or live trials")  # fmt: skip
        spec = dict(base_spec)
        spec.update({name: suggest(trial, name, s) for name, s in space.items()})
        settings = TrainSettings.from_config(train, spec)
        torch.manual_seed(int(tune["seed"]))
        model = build_model(spec)

        def report(epoch: int, row: dict[str, float]) -> None:
            value = _objective_value(row, objective)
            if math.isfinite(value):
                trial.report(value, epoch)
            if trial.should_prune():
                raise optuna.TrialPruned()

        result = fit(model, data, settings, int(tune["seed"]), on_epoch=report)
        best = result.history[result.best_epoch - 1]
        value = _objective_value(best, objective)
        trial.set_user_attr("best_epoch", result.best_epoch)
        trial.set_user_attr("epochs_run", len(result.history))
        return value if math.isfinite(value) else -math.inf

    def enough(study: optuna.Study, trial: optuna.trial.FrozenTrial) -> None:
        """Stop once the finished trials and the live ones elsewhere make ``trials``."""
        finished, live = progress()
        if finished + len(live) >= target:
            study.stop()

    # Workers sharing a study stop together once it holds ``trials`` finished trials, counting
    # each other's live trials, and a worker returns only when those have finished (or died).
    while True:
        finished, live = progress()
        if finished >= target:
            break
        if finished + len(live) >= target:
            time.sleep(WAIT_S)
            continue
        study.optimize(run_trial, n_trials=target - finished - len(live), gc_after_trial=True,
                       callbacks=[enough], catch=(SurplusTrial,))  # fmt: skip
    complete = study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))
    if not complete:
        raise RuntimeError(f"{family}: no tuning trial completed in study {study_name}")
    best = study.best_trial
    spec = dict(base_spec)
    spec.update(best.params)
    record = {
        "family": family,
        "spec": spec,
        "best_trial": best.number,
        "best_value": best.value,
        "objective": objective,
        "searched": sorted(space),
        "trials": {
            s.name.lower(): len(study.get_trials(deepcopy=False, states=(s,)))
            for s in optuna.trial.TrialState
        },  # fmt: skip
        "study_name": study_name,
        "storage": url.split("://")[0],
        "code_version": code_version("learning", "labels"),
        "platform": compute_platform(),
        "params": params,
        "params_hash": stable_hash(params),
    }
    rows = [
        {"number": t.number, "state": t.state.name.lower(),
         "value": t.value if t.value is not None else float("nan"),
         "epochs_run": t.user_attrs.get("epochs_run"), "params": str(t.params)}
        for t in study.get_trials(deepcopy=False)
    ]  # fmt: skip
    write_parquet(out_trials, pl.DataFrame(rows, infer_schema_length=None))
    write_json(out_best, record)
    log.info("best trial %d: %s = %.4f with %s", best.number, objective, best.value, best.params)
    return record
