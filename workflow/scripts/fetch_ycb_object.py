"""Snakemake wrapper: provide resources/ycb/<id>/ (graspstab.assets.ycb)."""

from pathlib import Path

from graspstab.assets.ycb import fetch_ycb_object
from graspstab.common.jobs import job
from graspstab.common.logs import setup_logging

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    setup_logging(sm.log[0])
    fetch_ycb_object(
        sm.wildcards.object,
        Path(sm.output.mesh).parent,
        local_dir=sm.params.local_dir,
        url_template=sm.params.url,
        sha256=sm.params.sha256,
        mesh_override=sm.params.mesh_override,
    )
