"""Snakemake wrapper: the chapter-4 figures of the learning studies (graspstab.figures),
drawn from the rule's named inputs only and written to its named outputs."""

from graspstab.common.jobs import job
from graspstab.common.logs import setup_logging
from graspstab.figures.artefacts import StudyArtefacts
from graspstab.figures.entry import plot_learning

sm = snakemake  # noqa: F821  (injected by Snakemake)
with job(sm):
    setup_logging(sm.log[0])
    plot_learning(
        StudyArtefacts.from_inputs(dict(sm.input.items())),
        dict(sm.output.items()),
        int(sm.params.dpi),
        int(sm.params.first_seed),
    )
