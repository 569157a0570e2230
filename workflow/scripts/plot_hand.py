"""Snakemake wrapper: the hand with its 120 candidates (fig. 3.3) and capsules (fig. 3.5a)."""

from pathlib import Path

from graspstab.common.jobs import job
from graspstab.common.logs import setup_logging
from graspstab.hand.figure import plot_candidates, plot_capsules

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    setup_logging(sm.log[0])
    hand_dir = Path(sm.input[0]).parent
    plot_candidates(hand_dir, Path(sm.output.candidates))
    plot_capsules(hand_dir, Path(sm.output.capsules))
