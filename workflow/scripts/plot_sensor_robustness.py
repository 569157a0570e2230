"""Snakemake wrapper: the sensor-robustness curves (graspstab.figures.robustness)."""

from pathlib import Path

from graspstab.common.io import read_json, read_parquet
from graspstab.common.jobs import job
from graspstab.common.logs import setup_logging
from graspstab.figures.robustness import plot_robustness

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    setup_logging(sm.log[0])
    plot_robustness(read_parquet(sm.input.runs), float(read_json(sm.input.summary)["chance"]),
                    Path(sm.output[0]), int(sm.params.dpi))  # fmt: skip
