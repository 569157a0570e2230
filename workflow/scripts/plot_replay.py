"""Snakemake wrapper: the replay trace figure of one example grasp (graspstab.replay.figure)."""

from graspstab.common.logs import setup_logging
from graspstab.replay.figure import plot_replay_example

sm = snakemake  # noqa: F821  (injected by Snakemake)
setup_logging(sm.log[0])
plot_replay_example(
    sm.input.summary,
    sm.input.traces,
    float(sm.params.timestep),
    sm.output[0],
    labels=dict(sm.params.labels),
)
