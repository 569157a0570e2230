"""Snakemake wrapper: the folds' early warning pooled over unseen objects
(graspstab.monitor.aggregate_fold_warning)."""

from graspstab.common.jobs import job
from graspstab.monitor.aggregate_fold_warning import aggregate_fold_warning

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    aggregate_fold_warning(
        list(sm.input.grasps), list(sm.input.thresholds), str(sm.params.protocol),
        dict(sm.params.bootstrap), sm.output.rows, sm.output.summary, log_file=sm.log[0],
    )  # fmt: skip
