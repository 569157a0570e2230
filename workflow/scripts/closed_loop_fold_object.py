"""Snakemake wrapper: one object's grasps under every closed-loop policy, with the models and
thresholds of the cross-validation fold in which it is a test object (closedloop)."""

from pathlib import Path

import torch

from graspstab.closedloop.closed_loop import closed_loop_object, write_closed_loop, write_timeline
from graspstab.closedloop.reflex import ReflexParams
from graspstab.closedloop.sources import build_fold_policies
from graspstab.common.cache import run_cached
from graspstab.common.io import read_json
from graspstab.common.jobs import job
from graspstab.common.logs import setup_logging
from graspstab.common.provenance import provenance

sm = snakemake  # noqa: F821  (injected by Snakemake)


def compute() -> None:
    setup_logging(sm.log[0])
    torch.set_num_threads(1)
    cl = dict(sm.params.closed_loop)
    inputs = dict(sm.input.items())
    names = list(sm.params.policies)
    checkpoints = {m: (inputs[f"checkpoint_{m}"], inputs[f"metrics_{m}"])
                   for m in ("cnn", "gru", "lstm") if m in names}  # fmt: skip
    policies = build_fold_policies(
        names, checkpoints=checkpoints, fold_thresholds=read_json(inputs["thresholds"]),
        proxy_dataset=Path(inputs["index"]).parent if "index" in inputs else None,
        assignment=dict(sm.params.assignment), threshold=dict(sm.params.threshold),
        latency_table=inputs["latency"], oracle_leads_s=list(cl["oracle_leads_s"]),
        shuffled=bool(cl["shuffled"]), thresholds=list(cl["thresholds"]),
    )  # fmt: skip
    # the shuffled controls deal from every object's tightening times, so they run in a second
    # job per object (closed_loop_fold_shuffled, with the pool as input); this one runs the rest
    pool = read_json(inputs["offsets"]) if "offsets" in inputs else None
    keep = ("none", "shuffled") if pool is not None else None
    policies = [p for p in policies if (p.kind in keep if keep else p.kind != "shuffled")]
    monitor = dict(sm.params.monitor)
    table, traces = closed_loop_object(
        sm.wildcards.object, Path(sm.input.object_xml).parent, Path(sm.input.hand[0]).parent,
        list(sm.input.grasps), dict(sm.params.replay), dict(sm.params.labels), policies,
        ReflexParams(**cl["reflex"]), stride=int(monitor["stride"]),
        debounce=int(monitor["debounce"]), arm_s=float(cl["arm_s"]), arming=cl["arming"],
        window_steps=round(float(cl["window_s"]) / float(sm.params.replay["timestep"])),
        fresh=bool(cl["fresh"]), shuffle_seed=int(cl["shuffle_seed"]),
        max_grasps=cl["folds"]["grasps"], timeline=None if pool else sm.params.timeline,
        offset_pool=pool,
    )  # fmt: skip
    if pool is not None:  # the no-reflex rows are the first job's
        table = table.filter(table["policy"] != "none")
    write_timeline(sm.output.timeline, table, traces)
    write_closed_loop(sm.output.table, table, {
        "object_id": sm.wildcards.object, "protocol": sm.wildcards.protocol,
        "policies": names,
        "thresholds": {p.name: p.threshold for p in policies if p.threshold is not None},
        "latency_s": {p.name: p.latency_s for p in policies if p.kind == "monitor"},
        "provenance": provenance("closedloop", {**cl, "replay": dict(sm.params.replay)}),
    })  # fmt: skip


# Content-addressed: restored from the cache when the same job ran before (docs/design.md).
with job(sm):
    run_cached(sm, ("closedloop/closed_loop", "closedloop/sources", "closedloop/sweep"), compute)
