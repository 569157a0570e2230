"""Snakemake wrapper: build the ORCA hand model, capsules and candidates (graspstab.hand)."""

from pathlib import Path

from graspstab.common.jobs import job
from graspstab.hand.build_hand import build_hand

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    build_hand(
        sm.input[0], Path(sm.output.hand_json).parent, dict(sm.params.hand), log_file=sm.log[0]
    )
