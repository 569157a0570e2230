"""Shared test fixtures: repository paths and the shared assets CI provides beside the checkout."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
CONFIG_DIR = REPO / "config"
SCHEMA = REPO / "workflow" / "schemas" / "config.schema.yaml"


def _shared_assets() -> Path:
    env = os.environ.get("GRASPSTAB_SHARED_ASSETS")
    return Path(env) if env else REPO.parent / "shared" / "assets"


SHARED_ASSETS = _shared_assets()
YCB_DIR = SHARED_ASSETS / "ycb"
HAND_DIR = SHARED_ASSETS / "orcahand_description"


@pytest.fixture(scope="session")
def ycb_dir() -> Path:
    """The local YCB copy (../shared/assets/ycb); the suite needs it, so its absence is an error."""
    if not YCB_DIR.is_dir():
        raise FileNotFoundError(
            f"{YCB_DIR} not found: the tests need the shared assets beside the checkout "
            "(or GRASPSTAB_SHARED_ASSETS pointing at them)"
        )
    return YCB_DIR


@pytest.fixture(scope="session")
def hand_assets_dir() -> Path:
    """The local ORCA hand description copy."""
    if not HAND_DIR.is_dir():
        raise FileNotFoundError(f"{HAND_DIR} not found (see ycb_dir)")
    return HAND_DIR


# Fast CoACD settings for tests that need a preprocessed object but not a faithful decomposition.
COARSE_COACD = {
    "threshold": 0.1,
    "max_convex_hull": 8,
    "preprocess_resolution": 30,
    "resolution": 500,
    "mcts_iterations": 20,
    "seed": 0,
}
COARSE_PREPROCESS = {
    "repair": {"sliver_max_faces": 16, "sliver_max_area_fraction": 0.01},
    "coacd": COARSE_COACD,
    "sdf": {"spacing": 0.0015, "margin": 0.05},
    "hull_points": {"count": 2000, "seed": 0},
    "contact": {"friction": [1.0, 0.005, 0.0001]},
}


@pytest.fixture(scope="session")
def built_hand_dir(hand_assets_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The hand artefacts (hand.xml, hand.json, capsules.json, candidates), built once."""
    from graspstab.hand.build_hand import build_hand
    from graspstab.hand.params import DEFAULT_PARAMS

    out = tmp_path_factory.mktemp("built_hand")
    build_hand(hand_assets_dir, out, DEFAULT_PARAMS)
    return out


@pytest.fixture(scope="session")
def foam_brick_dir(ycb_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The foam brick preprocessed once (mesh.obj, sdf.npz at 1.5 mm, hull_points.npy, ...)."""
    from graspstab.objects.preprocess_object import preprocess_object

    out = tmp_path_factory.mktemp("object_061_foam_brick")
    preprocess_object(
        "061_foam_brick", ycb_dir / "061_foam_brick" / "textured.obj", out, 0.028, COARSE_PREPROCESS
    )
    return out


@pytest.fixture(scope="session")
def run(tmp_path_factory, ycb_dir, hand_assets_dir):
    """The end-to-end toy run (tests/toy_workflow.py), shared by test_workflow and test_report:
    (workdir, env, config)."""
    from tests.toy_workflow import CONFIG, snakemake_run

    workdir = tmp_path_factory.mktemp("wf")
    env = dict(os.environ, GRASPSTAB_YCB_DIR=str(ycb_dir), GRASPSTAB_HAND_DIR=str(hand_assets_dir))
    config = CONFIG
    proc = snakemake_run(workdir, "results/report.html", *config, env=env)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-4000:]
    return workdir, env, config
