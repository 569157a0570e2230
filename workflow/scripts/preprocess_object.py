"""Snakemake wrapper: preprocess one object (graspstab.objects.preprocess_object)."""

from pathlib import Path

from graspstab.common.cache import run_cached
from graspstab.common.jobs import job
from graspstab.objects.preprocess_object import preprocess_object

sm = snakemake  # noqa: F821  (injected by Snakemake)


def compute() -> None:
    preprocess_object(
        sm.wildcards.object,
        sm.input.mesh,
        Path(sm.output.meta).parent,
        mass=sm.params.mass,
        params=dict(sm.params.preprocess),
        rotation_deg=sm.params.rotation_deg,
        log_file=sm.log[0],
    )


# Content-addressed: restored from the cache when the same job ran before (docs/design.md).
with job(sm):
    run_cached(sm, ("objects/preprocess_object",), compute)
