"""Snakemake wrapper: the chapter-4 figures of the learning studies (graspstab.learning.figures)."""

from pathlib import Path

from graspstab.common.logs import setup_logging
from graspstab.learning.figures import plot_learning

sm = snakemake  # noqa: F821  (injected by Snakemake)
setup_logging(sm.log[0])
plot_learning(
    Path("results"), Path(sm.output[0]).parent, int(sm.params.dpi), int(sm.params.first_seed)
)
