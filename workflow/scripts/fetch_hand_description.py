"""Snakemake wrapper: provide resources/orcahand_description/ (graspstab.assets.hand)."""

from graspstab.assets.hand import fetch_hand_description, read_manifest
from graspstab.common.jobs import job
from graspstab.common.logs import setup_logging

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    setup_logging(sm.log[0])
    fetch_hand_description(
        sm.output[0],
        local_dir=sm.params.local_dir,
        url_template=sm.params.url,
        commit=sm.params.commit,
        manifest=read_manifest(sm.input.manifest) if sm.input.get("manifest") else None,
    )
