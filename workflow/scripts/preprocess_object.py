"""Snakemake wrapper: preprocess one object (graspstab.objects.preprocess_object)."""

from pathlib import Path

from graspstab.objects.preprocess_object import preprocess_object

sm = snakemake  # noqa: F821  (injected by Snakemake)
preprocess_object(
    sm.wildcards.object,
    sm.input.mesh,
    Path(sm.output.meta).parent,
    mass=sm.params.mass,
    params=dict(sm.params.preprocess),
    rotation_deg=sm.params.rotation_deg,
    log_file=sm.log[0],
)
