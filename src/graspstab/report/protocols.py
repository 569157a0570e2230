"""The report's "Two protocols side by side" section as the run gives it: the main run's and the
creep-free benchmark's artefacts set beside each other (report/creep_free.py renders them), or a
note on how to turn the benchmark on."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from graspstab.figures.artefacts import StudyArtefacts
from graspstab.report import html as H
from graspstab.report.creep_free import Benchmark, creep_free_section


def protocols_parts(
    config: Mapping[str, Any],
    creep_free: Mapping[str, Any] | None,
    dataset: Path | None,
    speeds: Path | None,
    replay_outcomes: Path | None,
    learning: StudyArtefacts | None,
    figures: Mapping[str, Path],
) -> list[str]:
    """The two protocols side by side, when the run has the creep-free benchmark (``creep_free``:
    its named inputs, prefix stripped); else a note on how to turn it on."""
    if (not creep_free or dataset is None or speeds is None or replay_outcomes is None
            or learning is None):  # fmt: skip
        return [
            H.heading(2, "protocols", "Two protocols side by side: gravity and the load ramp"),
            '<p class="note">This run has no creep-free benchmark (creep_free.enabled is false). '
            "<code>--config 'creep_free={enabled: true}'</code> replays the same grasps under the "
            "strict contact model with a rising load and sets the two side by side here "
            '(docs/protocols.md, "The creep-free load ramp").</p>',
        ]
    main = Benchmark(
        name=f"gravity ({config['replay']['contact']['name']} contact model)",
        dataset=dataset, speeds=speeds, replay_outcomes=replay_outcomes, studies=learning,
        speeds_figure=figures.get("unstable_speeds"),
        sweep_windows_s=[float(w) for w in config["sweep"]["windows_s"]],
    )  # fmt: skip
    cf = config["creep_free"]
    load = "hidden-onset disturbance" if cf["load"] == "perturb" else "load ramp"
    ramp = Benchmark(
        name=f"{load} ({cf['contact']['name']} contact model)",
        dataset=Path(creep_free["dataset"]), speeds=Path(creep_free["speeds"]),
        replay_outcomes=Path(creep_free["replay_outcomes"]),
        studies=StudyArtefacts.from_inputs(creep_free, prefix="study_"),
        speeds_figure=Path(creep_free["speeds_figure"]),
        sweep_windows_s=[float(w) for w in cf["sweep_windows_s"]],
    )  # fmt: skip
    replay = {"protocol": cf["load"], cf["load"]: config["replay"][cf["load"]]}
    return [creep_free_section(main, ramp, replay)]
