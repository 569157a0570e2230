"""Snakemake wrapper: the friction-ratio proxy on the baseline dataset (evaluation.studies,
4.7); the dataset folder is the one holding the rule's declared index, windows and statistics."""

from pathlib import Path

from graspstab.common.jobs import job
from graspstab.evaluation import studies

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    studies.evaluate_proxy(Path(sm.input.index).parent, sm.output[0], log_file=sm.log[0])
