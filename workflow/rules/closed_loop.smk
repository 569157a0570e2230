# Closed loop (our extension, docs/extensions.md "Closed loop"): every test object's grasps
# replayed under each policy (no reflex, always, oracle, the proxy, the learned pick, each family)
# with the grip reflex in the loop, per protocol. Each family's monitor is its first-seed sweep
# model at closed_loop.window_s under that protocol, with its validation-selected threshold; the
# proxy's threshold comes from the same dataset's validation windows; the pick is the reference
# protocol's export (monitor.smk) and runs under the reference protocol only.

from graspstab.closedloop.closed_loop import protocol_params
from graspstab.closedloop.policies import policy_names

CL = config["closed_loop"]
CL_MS = ms_of(CL["window_s"])
# The config validator (graspstab.config.relations) has checked that the creep-free protocol has
# its benchmark and that closed_loop.window_s is a sweep window of each protocol.
CL_ROOTS = {"reference": "results", "creep_free": CREEP_FREE}


def closed_loop_policies(protocol):
    """The policies run under ``protocol`` (the pick only where its export was trained)."""
    return [p for p in CL["policies"] if p != "pick" or protocol == "reference"]


def timeline_policy(protocol):
    """The policy the timeline figure shows: the pick, else the first learned family, else the
    proxy, else the first policy with a reflex (None: no reflex run at all)."""
    names = closed_loop_policies(protocol)
    for choice in ("pick", *MODELS, "proxy", *(p for p in names if p != "none")):
        if choice in names:
            return choice
    return None


def closed_loop_inputs(wildcards):
    """A protocol's monitors: checkpoints and metrics, the pick's export, the proxy's dataset
    and the latency table."""
    root, names = CL_ROOTS[wildcards.protocol], closed_loop_policies(wildcards.protocol)
    out = {"latency": rules.measure_latency.output[0]}
    for m in (m for m in MODELS if m in names):
        out[f"checkpoint_{m}"] = sweep_first_seed(m, CL_MS, "model.pt", root)
        out[f"metrics_{m}"] = sweep_first_seed(m, CL_MS, "metrics.json", root)
    if "pick" in names:
        out["pick"] = rules.export_pick.output.onnx
    if "proxy" in names:
        out.update(dataset_inputs(f"{root}/datasets/sweep/w{CL_MS}ms"))
    if "budget" in CL["thresholds"]:  # the grasp-level evaluation's budget thresholds
        out["monitor_summary"] = (rules.evaluate_monitor.output.summary
                                  if wildcards.protocol == "reference"
                                  else f"{CREEP_FREE}/monitor/summary.json")  # fmt: skip
    return out


def closed_loop_tables(protocols=None):
    """The per-object closed-loop tables: protocol (all, or ``protocols``) x test object."""
    tests = [o for o, s in object_splits().items() if s == "test"]
    return expand("results/closed_loop/{protocol}/{object}.parquet",
                  protocol=protocols or CL["protocols"], object=tests)  # fmt: skip


CL_SUMMARY = "results/closed_loop/summary/{protocol}"


wildcard_constraints:
    protocol="reference|creep_free",


rule closed_loop_object:
    input:
        unpack(closed_loop_inputs),
        grasps=shard_tables,
        object_xml="results/objects/{object}/object.xml",
        hand=rules.build_hand.output,
    output:
        table="results/closed_loop/{protocol}/{object}.parquet",
        timeline="results/closed_loop/{protocol}/timeline/{object}.npz",
    params:
        replay=lambda wc: protocol_params(config, wc.protocol),
        # the protocol's labelling rules (the creep-free benchmark's own source)
        labels=lambda wc: config["labels"] if wc.protocol == "reference" else creep_free_labels(),
        closed_loop=CL,
        policies=lambda wc: closed_loop_policies(wc.protocol),
        timeline=lambda wc: timeline_policy(wc.protocol),
        monitor=config["monitor"],
        threshold=config["train"]["threshold"],
    threads: 1
    resources:
        mem_mb=3000,
        runtime=240,
    log:
        "results/logs/closed_loop_object/{protocol}_{object}.log",
    benchmark:
        "results/benchmarks/closed_loop_object/{protocol}_{object}.tsv"
    script:
        "../scripts/closed_loop_object.py"


rule aggregate_closed_loop:
    input:
        lambda wc: closed_loop_tables([wc.protocol]),
    output:
        policies=f"{CL_SUMMARY}/policies.parquet",
        comparisons=f"{CL_SUMMARY}/comparisons.parquet",
        worse=f"{CL_SUMMARY}/worse.parquet",
        tradeoff=f"{CL_SUMMARY}/tradeoff.parquet",
        summary=f"{CL_SUMMARY}/summary.json",
    params:
        # the row labels the object jobs write: each oracle lead, each monitor's shuffled control
        policies=lambda wc: policy_names(closed_loop_policies(wc.protocol), CL["oracle_leads_s"],
                                         CL["shuffled"], CL["thresholds"]),
        bootstrap=CL["bootstrap"],
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    log:
        "results/logs/aggregate_closed_loop/{protocol}.log",
    benchmark:
        "results/benchmarks/aggregate_closed_loop/{protocol}.tsv"
    script:
        "../scripts/aggregate_closed_loop.py"


rule plot_closed_loop:
    input:
        summary=rules.aggregate_closed_loop.output.summary,
        tradeoff=rules.aggregate_closed_loop.output.tradeoff,
        policies=rules.aggregate_closed_loop.output.policies,
        timelines=lambda wc: [p.replace(".parquet", ".npz").replace(
            f"/{wc.protocol}/", f"/{wc.protocol}/timeline/")
            for p in closed_loop_tables([wc.protocol])],  # fmt: skip
    output:
        tradeoff="results/figures/closed_loop/{protocol}_tradeoff.png",
        timeline="results/figures/closed_loop/{protocol}_timeline.png",
    params:
        v_slip=config["labels"]["v_slip"],
        dt=config["replay"]["timestep"],
        dpi=config["report"]["figure_dpi"],
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    log:
        "results/logs/plot_closed_loop/{protocol}.log",
    benchmark:
        "results/benchmarks/plot_closed_loop/{protocol}.tsv"
    script:
        "../scripts/plot_closed_loop.py"


# The summaries and figures per protocol, as named inputs of the report
# (closed_loop_<protocol>_<artefact>).
CLOSED_LOOP_ARTEFACTS = {
    f"{p}_{k}": v.replace("{protocol}", p)
    for p in (CL["protocols"] if CL["enabled"] else [])
    for k, v in [*rules.aggregate_closed_loop.output.items(),
                 *((f"{k}_figure", v) for k, v in rules.plot_closed_loop.output.items())]
}  # fmt: skip


localrules:
    closed_loop,


rule closed_loop:
    """Target: every closed-loop table and summary (snakemake --cores 2 closed_loop --config ...)."""
    input:
        closed_loop_tables(),
        CLOSED_LOOP_ARTEFACTS.values(),


# The closed loop over the cross-validation folds (closed_loop.folds; docs/extensions.md "Closed
# loop"): every object's grasps (the lowest ids, closed_loop.folds.grasps of them) under its test
# fold's own models, the proxy's threshold on that fold's validation windows and the budget
# thresholds evaluate_fold_monitor chose on its validation grasps; one summary per protocol with
# intervals by bootstrap over grasps clustered by object. The config validator has checked that
# each protocol's folds have those thresholds (crossval.early_warning) and that the windows agree.
CLF = CL["folds"]
CLF_SUMMARY = "results/closed_loop/folds/summary/{protocol}"


def fold_of(obj):
    """The fold in which ``obj`` is a test object."""
    return next(k for k, a in enumerate(fold_assignments()) if a.get(obj) == "test")


def closed_loop_fold_inputs(wildcards):
    """An object's test fold: its models, its budget thresholds, the dataset its proxy threshold
    is chosen on, and the latency table."""
    root, k = CV_ROOTS[wildcards.protocol], fold_of(wildcards.object)
    out = {"latency": rules.measure_latency.output[0],
           "thresholds": f"{root}/monitor/crossval/f{k}/thresholds.json"}  # fmt: skip
    out.update({k2: v for k2, v in fold_model_inputs(root, k).items()
                if k2.removeprefix("checkpoint_").removeprefix("metrics_") in CL["policies"]})
    if "proxy" in CL["policies"]:
        out.update(dataset_inputs(f"{root}/datasets/sweep/w{CV_MS}ms"))
    return out


def closed_loop_fold_tables(protocol, part=""):
    """Every object's table of a protocol: its own policies, or (part "shuffled/") the shuffled
    controls, which deal from every object's tightening times."""
    return expand("results/closed_loop/folds/{protocol}/{part}{object}.parquet",
                  protocol=protocol, part=part, object=object_ids())  # fmt: skip


rule closed_loop_fold_object:
    input:
        unpack(closed_loop_fold_inputs),
        grasps=shard_tables,
        object_xml="results/objects/{object}/object.xml",
        hand=rules.build_hand.output,
    output:
        table="results/closed_loop/folds/{protocol}/{object}.parquet",
        timeline="results/closed_loop/folds/{protocol}/timeline/{object}.npz",
    params:
        replay=lambda wc: protocol_params(config, wc.protocol),
        labels=lambda wc: config["labels"] if wc.protocol == "reference" else creep_free_labels(),
        closed_loop=CL,
        policies=CL["policies"],
        timeline=lambda wc: timeline_policy(wc.protocol),
        monitor=config["monitor"],
        threshold=config["train"]["threshold"],
        assignment=lambda wc: fold_assignments()[fold_of(wc.object)],
    threads: 1
    resources:
        mem_mb=3000,
        runtime=240,
    log:
        "results/logs/closed_loop_fold_object/{protocol}_{object}.log",
    benchmark:
        "results/benchmarks/closed_loop_fold_object/{protocol}_{object}.tsv"
    script:
        "../scripts/closed_loop_fold_object.py"


rule closed_loop_fold_offsets:
    input:
        lambda wc: closed_loop_fold_tables(wc.protocol),
    output:
        "results/closed_loop/folds/{protocol}/offsets.json",
    params:
        dt=config["replay"]["timestep"],
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    log:
        "results/logs/closed_loop_fold_offsets/{protocol}.log",
    benchmark:
        "results/benchmarks/closed_loop_fold_offsets/{protocol}.tsv"
    script:
        "../scripts/closed_loop_fold_offsets.py"


use rule closed_loop_fold_object as closed_loop_fold_shuffled with:
    input:
        unpack(closed_loop_fold_inputs),
        grasps=shard_tables,
        object_xml="results/objects/{object}/object.xml",
        hand=rules.build_hand.output,
        offsets=rules.closed_loop_fold_offsets.output[0],
    output:
        table="results/closed_loop/folds/{protocol}/shuffled/{object}.parquet",
        timeline="results/closed_loop/folds/{protocol}/shuffled/timeline/{object}.npz",
    log:
        "results/logs/closed_loop_fold_shuffled/{protocol}_{object}.log",
    benchmark:
        "results/benchmarks/closed_loop_fold_shuffled/{protocol}_{object}.tsv"


rule aggregate_closed_loop_folds:
    input:
        lambda wc: closed_loop_fold_tables(wc.protocol)
        + (closed_loop_fold_tables(wc.protocol, "shuffled/") if CL["shuffled"] else []),
    output:
        policies=f"{CLF_SUMMARY}/policies.parquet",
        comparisons=f"{CLF_SUMMARY}/comparisons.parquet",
        worse=f"{CLF_SUMMARY}/worse.parquet",
        tradeoff=f"{CLF_SUMMARY}/tradeoff.parquet",
        summary=f"{CLF_SUMMARY}/summary.json",
    params:
        policies=policy_names(CL["policies"], CL["oracle_leads_s"], CL["shuffled"],
                              CL["thresholds"]),
        # every object a test object once: intervals resample whole objects
        bootstrap={**CL["bootstrap"], "unit": "object"},
    threads: 1
    resources:
        mem_mb=2000,
        runtime=20,
    log:
        "results/logs/aggregate_closed_loop_folds/{protocol}.log",
    benchmark:
        "results/benchmarks/aggregate_closed_loop_folds/{protocol}.tsv"
    script:
        "../scripts/aggregate_closed_loop.py"


CLOSED_LOOP_ARTEFACTS |= {
    f"folds_{p}_{k}": v.replace("{protocol}", p)
    for p in (CL["protocols"] if CLF["enabled"] else [])
    for k, v in rules.aggregate_closed_loop_folds.output.items()
}
