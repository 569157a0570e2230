"""Snakemake wrapper: every monitor's tightening times from arming over every object's closed-loop
table of a protocol, the pool its shuffled control deals from (closedloop.closed_loop)."""

import polars as pl

from graspstab.closedloop.closed_loop import tightening_offsets
from graspstab.common.io import read_parquet, write_json
from graspstab.common.jobs import job

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    table = pl.concat([read_parquet(p) for p in sm.input], how="diagonal_relaxed")
    write_json(sm.output[0], tightening_offsets(table, float(sm.params.dt)))
