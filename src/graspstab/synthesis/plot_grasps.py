"""Figures entry point of the synthesis stage: one pre-grasp, the gallery, the energy histograms."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

from graspstab.synthesis import figure
from graspstab.synthesis.kinematics import BatchedHandKinematics
from graspstab.synthesis.pregrasp import inflate_hull, sample_pregrasps
from graspstab.synthesis.summarise_grasps import read_grasp_tables

log = logging.getLogger(__name__)

#: The object of the pre-grasp illustration when the run has it (thesis fig. 3.4 uses the brick).
PREGRASP_OBJECT = "061_foam_brick"


def plot_grasps(
    tables: Sequence[Path],
    object_dirs: Sequence[Path],
    hand_dir: Path,
    pregrasp_params: dict[str, Any],
    seed: int,
    out_pregrasp: Path,
    out_gallery: Path,
    out_histograms: Path,
) -> None:
    """Draw the three synthesis figures from the grasp tables and the object/hand artefacts."""
    dirs = {Path(d).name: Path(d) for d in object_dirs}
    chosen = PREGRASP_OBJECT if PREGRASP_OBJECT in dirs else sorted(dirs)[0]
    mesh = trimesh.load(dirs[chosen] / "mesh.obj", force="mesh", process=False)
    kin = BatchedHandKinematics(hand_dir)
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, 3, 1, 4])))
    pre = sample_pregrasps(mesh, kin, 1, rng, pregrasp_params)
    hull = inflate_hull(mesh, float(pregrasp_params["inflation"]))
    figure.plot_pregrasp(out_pregrasp, mesh, hull, pre, hand_dir, index=0, object_id=chosen)
    grasps = read_grasp_tables(tables)
    figure.plot_grasp_gallery(out_gallery, grasps, dirs, hand_dir)
    figure.plot_energy_histograms(out_histograms, grasps)
    log.info("synthesis figures written (%d grasps, %d objects)", grasps.height, len(dirs))
