"""Snakemake wrapper: pre-grasp figure, grasp gallery, energy histograms (graspstab.synthesis)."""

from pathlib import Path

from graspstab.common.jobs import job
from graspstab.common.logs import setup_logging
from graspstab.synthesis.plot_grasps import plot_grasps

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    setup_logging(sm.log[0])
    plot_grasps(
        tables=[Path(p) for p in sm.input.tables],
        object_dirs=[Path(p).parent for p in sm.input.objects],
        hand_dir=Path(sm.input.hand[0]).parent,
        pregrasp_params=dict(sm.params.pregrasp),
        seed=int(sm.params.seed),
        out_pregrasp=Path(sm.output.pregrasp),
        out_gallery=Path(sm.output.gallery),
        out_histograms=Path(sm.output.histograms),
    )
