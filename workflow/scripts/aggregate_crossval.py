"""Snakemake wrapper: the k-fold study of one protocol (graspstab.evaluation.studies); object size
is the largest extent of each object's preprocessed mesh (its meta.json)."""

from pathlib import Path

from graspstab.common.io import read_json
from graspstab.common.jobs import job
from graspstab.evaluation import studies

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    props = {o: dict(v) for o, v in sm.params.properties.items()}
    for path in sm.input.meta:
        props[Path(path).parent.name]["size"] = float(max(read_json(path)["extents"]))
    studies.aggregate_crossval(
        list(sm.input.predictions),
        list(sm.input.metrics),
        list(sm.params.run_keys),
        Path(sm.input.index).parent,
        props,
        sm.params.protocol,
        dict(sm.params.bootstrap),
        Path(sm.output.summary).parent,
        log_file=sm.log[0],
    )
