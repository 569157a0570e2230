# Object-level k-fold cross-validation (our extension; docs/results.md "Generalisation across
# objects"): every object a test object once, validation from the next fold, thresholds and
# normalisation from each fold's own training and validation objects. One training job is one
# protocol x variant x family x fold x seed on the sweep's same-end dataset at crossval.window_s;
# one aggregation per protocol scores the friction-ratio proxy and the paired comparisons.

from graspstab.evaluation.folds import kfold_assignments

CV = config["crossval"]
CV_MS = ms_of(CV["window_s"])
CV_ROOTS = {"reference": "results", "creep_free": CREEP_FREE}
CV_VARIANTS = ["forces"] + list(CV["variants"])
# what each fairness variant changes: the window features, or the train group's threshold rule
CV_FEATURES = {
    "ratio": {"ratio_channel": True},
    "gain": {"window_norm": "gain"},
}


wildcard_constraints:
    variant="|".join(CV_VARIANTS),
    fold=r"[0-9]+",


@functools.cache
def fold_assignments():
    """The k folds' object -> split assignments (graspstab.evaluation.folds)."""
    return kfold_assignments(object_ids(), CV["k"], CV["fold_seed"], CV["val_folds"])


def crossval_keys():
    """(variant, family, fold, seed) of every fold run: the plain forces for every family, each
    fairness variant for the variant families."""
    pairs = [("forces", m) for m in CV["families"]] + [
        (v, m) for v in CV["variants"] for m in CV["variant_families"]
    ]
    return [
        {"variant": v, "family": m, "fold": k, "seed": s}
        for v, m in pairs
        for k in range(CV["k"])
        for s in CV["seeds"]
    ]


def crossval_runs(root, name):
    return [
        f"{root}/train/crossval/{r['variant']}/{r['family']}/f{r['fold']}/seed{r['seed']}/{name}"
        for r in crossval_keys()
    ]


def crossval_train(variant):
    """The train group a variant trains with (best_f1: the threshold rule, nothing else)."""
    train = dict(config["train"])
    if variant == "best_f1":
        train["threshold"] = {**train["threshold"], "rule": "best_f1"}
    return train


def crossval_features(variant):
    feats = CV_FEATURES.get(variant)
    return {**feats, "ratio_eps": CV["ratio_eps"], "gain_eps": CV["gain_eps"]} if feats else None


def object_properties():
    """Mass, shape class and size (largest extent [m], from preprocessing) of every object."""
    props = {}
    for o in object_ids():
        entry = config["objects"]["items"][o]
        props[o] = {"mass": entry["mass"], "shape": entry.get("shape", "unclassified")}
    return props


rule train_fold_model:
    input:
        **dataset_inputs(f"results/datasets/sweep/w{CV_MS}ms"),
    output:
        # the checkpoint: each fold's monitors score its validation and test replays
        **run_outputs("results/train/crossval/{variant}/{model}/f{fold}/seed{seed}"),
    params:
        spec=lambda wc: config["sweep"]["models"][wc.model],
        pooling=config["sweep"]["recurrent_pooling"],
        train=lambda wc: crossval_train(wc.variant),
        assignment=lambda wc: fold_assignments()[int(wc.fold)],
        features=lambda wc: crossval_features(wc.variant),
        extra=lambda wc: {"fold": int(wc.fold), "variant": wc.variant},
    threads: 1
    resources:
        mem_mb=3000,
        runtime=120,
    log:
        "results/logs/train_fold_model/{variant}_{model}_f{fold}_seed{seed}.log",
    benchmark:
        "results/benchmarks/train_fold_model/{variant}_{model}_f{fold}_seed{seed}.tsv"
    script:
        "../scripts/train_model.py"


rule aggregate_crossval:
    input:
        predictions=crossval_runs("results", "predictions.parquet"),
        metrics=crossval_runs("results", "metrics.json"),
        meta=object_outputs("meta.json"),
        **dataset_inputs(f"results/datasets/sweep/w{CV_MS}ms"),
    output:
        per_object="results/studies/crossval/per_object.parquet",
        pooled="results/studies/crossval/pooled.parquet",
        folds="results/studies/crossval/folds.parquet",
        paired="results/studies/crossval/paired.parquet",
        pooled_still="results/studies/crossval/pooled_still.parquet",
        per_object_still="results/studies/crossval/per_object_still.parquet",
        summary="results/studies/crossval/summary.json",
    params:
        run_keys=crossval_keys(),
        properties=object_properties(),
        protocol="reference",
        bootstrap=CV["bootstrap"],
        assignments=lambda wc: fold_assignments(),
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    log:
        "results/logs/aggregate_crossval/reference.log",
    benchmark:
        "results/benchmarks/aggregate_crossval/reference.tsv"
    script:
        "../scripts/aggregate_crossval.py"


rule plot_crossval:
    input:
        per_object=rules.aggregate_crossval.output.per_object,
        summary=rules.aggregate_crossval.output.summary,
    output:
        "results/figures/crossval/per_object.png",
    params:
        dpi=config["report"]["figure_dpi"],
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    log:
        "results/logs/plot_crossval/reference.log",
    benchmark:
        "results/benchmarks/plot_crossval/reference.tsv"
    script:
        "../scripts/plot_crossval.py"


if "creep_free" in CV["protocols"]:

    use rule train_fold_model as train_fold_model_creep_free with:
        input:
            **dataset_inputs(f"{CREEP_FREE}/datasets/sweep/w{CV_MS}ms"),
        output:
            **run_outputs(
                f"{CREEP_FREE}/train/crossval/{{variant}}/{{model}}/f{{fold}}/seed{{seed}}"
            ),
        log:
            "results/logs/train_fold_model_creep_free/{variant}_{model}_f{fold}_seed{seed}.log",
        benchmark:
            "results/benchmarks/train_fold_model_creep_free/{variant}_{model}_f{fold}_seed{seed}.tsv"

    use rule aggregate_crossval as aggregate_crossval_creep_free with:
        input:
            predictions=crossval_runs(CREEP_FREE, "predictions.parquet"),
            metrics=crossval_runs(CREEP_FREE, "metrics.json"),
            meta=object_outputs("meta.json"),
            **dataset_inputs(f"{CREEP_FREE}/datasets/sweep/w{CV_MS}ms"),
        output:
            **{k: f"{CREEP_FREE}/studies/crossval/{Path(v).name}"
               for k, v in rules.aggregate_crossval.output.items()},
        params:
            run_keys=crossval_keys(),
            properties=object_properties(),
            protocol="creep_free",
            bootstrap=CV["bootstrap"],
            assignments=lambda wc: fold_assignments(),
        log:
            "results/logs/aggregate_crossval_creep_free/creep_free.log",
        benchmark:
            "results/benchmarks/aggregate_crossval_creep_free/creep_free.tsv"

    use rule plot_crossval as plot_crossval_creep_free with:
        input:
            per_object=rules.aggregate_crossval_creep_free.output.per_object,
            summary=rules.aggregate_crossval_creep_free.output.summary,
        output:
            "results/figures/creep_free/crossval/per_object.png",
        log:
            "results/logs/plot_crossval_creep_free/creep_free.log",
        benchmark:
            "results/benchmarks/plot_crossval_creep_free/creep_free.tsv"


# Early warning over the folds (crossval.early_warning: the protocols it runs for): each fold's
# plain-forces models and the proxy score the fold's validation and test replays as the streaming
# monitor would, thresholds for monitor.early_warning's false-warning budget from validation;
# protocols it names that are not cross-validated are skipped;
# one aggregation per protocol pools every object's test grasps (graspstab.monitor.fold_warning).
CV_WARNING = [p for p in CV["early_warning"] if p in CV["protocols"]]


def fold_replays(kind, root, fold):
    """The replay tables or traces of one fold's validation and test objects."""
    a = fold_assignments()[int(fold)]
    return [p for p in replay_outputs(kind, root) if a.get(Path(p).parent.name) in ("val", "test")]


def fold_model_inputs(root, fold):
    """Each family's plain-forces run of the fold at its first seed: checkpoint and metrics."""
    seed = CV["seeds"][0]
    run = f"{root}/train/crossval/forces/{{m}}/f{fold}/seed{seed}"
    return {
        **{f"checkpoint_{m}": run.format(m=m) + "/model.pt" for m in CV["families"]},
        **{f"metrics_{m}": run.format(m=m) + "/metrics.json" for m in CV["families"]},
    }


for _p in CV_WARNING:
    _root = CV_ROOTS[_p]
    _rule = "" if _p == "reference" else f"_{_p}"

    rule:
        name:
            f"evaluate_fold_monitor{_rule}"
        input:
            unpack(lambda wc, root=_root: fold_model_inputs(root, wc.fold)),
            tables=lambda wc, root=_root: fold_replays("replays", root, wc.fold),
            traces=lambda wc, root=_root: fold_replays("traces", root, wc.fold),
        output:
            grasps=f"{_root}/monitor/crossval/f{{fold}}/grasps.parquet",
            thresholds=f"{_root}/monitor/crossval/f{{fold}}/thresholds.json",
        params:
            assignment=lambda wc: fold_assignments()[int(wc.fold)],
            labels=config["labels"] if _p == "reference" else creep_free_labels(),
            dt=config["replay"]["timestep"],
            monitor=config["monitor"],
        threads: 1
        resources:
            mem_mb=3000,
            runtime=60,
        log:
            f"results/logs/evaluate_fold_monitor{_rule}/f{{fold}}.log",
        benchmark:
            f"results/benchmarks/evaluate_fold_monitor{_rule}/f{{fold}}.tsv"
        script:
            "../scripts/evaluate_fold_monitor.py"

    rule:
        name:
            f"aggregate_fold_warning{_rule}"
        input:
            grasps=expand(f"{_root}/monitor/crossval/f{{fold}}/grasps.parquet",
                          fold=range(CV["k"])),
            thresholds=expand(f"{_root}/monitor/crossval/f{{fold}}/thresholds.json",
                              fold=range(CV["k"])),
        output:
            rows=f"{_root}/studies/crossval/early_warning.parquet",
            summary=f"{_root}/studies/crossval/early_warning.json",
        params:
            protocol=_p,
            bootstrap=CV["bootstrap"],
        threads: 1
        resources:
            mem_mb=1000,
            runtime=10,
        log:
            f"results/logs/aggregate_fold_warning{_rule}/{_p}.log",
        benchmark:
            f"results/benchmarks/aggregate_fold_warning{_rule}/{_p}.tsv"
        script:
            "../scripts/aggregate_fold_warning.py"


# The study's artefacts per protocol, as named inputs of the report (<protocol>_<artefact>).
CROSSVAL_ARTEFACTS = {
    f"{p}_{k}": (f"{CV_ROOTS[p]}/studies/crossval/{Path(v).name}")
    for p in CV["protocols"]
    for k, v in rules.aggregate_crossval.output.items()
} | {
    f"{p}_figure": (
        "results/figures/crossval/per_object.png"
        if p == "reference"
        else "results/figures/creep_free/crossval/per_object.png"
    )
    for p in CV["protocols"]
}
CROSSVAL_ARTEFACTS |= {
    f"{p}_early_warning": f"{CV_ROOTS[p]}/studies/crossval/early_warning.json"
    for p in CV_WARNING
}
