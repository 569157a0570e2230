"""Shared test fixtures: repository paths, and the assets obtained exactly as the workflow does.

The YCB meshes and the ORCA hand come from the workflow's own settings: the variables
``GRASPSTAB_YCB_DIR`` / ``GRASPSTAB_HAND_DIR`` (config ``assets.ycb_dir`` / ``assets.hand_dir``),
else the checksummed download (``assets.ycb_url`` / ``assets.hand_url``) into the workflow's
cache ``resources/``, by the fetch functions the rules call. ``pytest --workflow-config KEY=VALUE``
takes what ``snakemake --config`` takes (e.g. ``'assets={ycb_url: http://mirror/{id}.tgz}'``).
"""

from __future__ import annotations

import fcntl
import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[1]
CONFIG_DIR = REPO / "config"
SCHEMA = REPO / "workflow" / "schemas" / "config.schema.yaml"
# The workflow's own cache of obtained inputs (rules fetch_ycb_object, fetch_hand_description).
RESOURCES = REPO / "resources"
ASSET_VARIABLES = ("GRASPSTAB_YCB_DIR", "GRASPSTAB_HAND_DIR")
ASSET_HELP = (
    "Set GRASPSTAB_YCB_DIR to a folder holding <id>/textured.obj (the YCB google_16k meshes) and "
    "GRASPSTAB_HAND_DIR to an orcahand_description copy (the folder holding v2/ and LICENSE), or "
    "give the tests network access so they can download the pinned archives into resources/."
)


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--workflow-config",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a config override as snakemake --config takes it; the tests obtain their assets "
        "with the resulting assets.* settings (repeatable)",
    )


def workflow_config(config: pytest.Config) -> dict[str, Any]:
    """The resolved workflow config under this session's ``--workflow-config`` overrides."""
    from graspstab.config import load_config
    from graspstab.config.show import parse_snakemake_config

    return load_config(
        CONFIG_DIR,
        SCHEMA,
        snakemake_config=parse_snakemake_config(config.getoption("workflow_config")),
        check_files=False,
    )


@contextmanager
def _assets_lock() -> Iterator[None]:
    """One process at a time fills resources/ (parallel test workers share it)."""
    RESOURCES.mkdir(exist_ok=True)
    with open(RESOURCES / ".tests.lock", "w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _recorded(dest: Path, key: str, value: str | None) -> bool:
    """Whether ``dest`` holds a finished fetch whose source.json records ``key == value``."""
    try:
        record = json.loads((dest / "source.json").read_text())
    except (OSError, ValueError):
        return False
    return value is not None and record.get(key) == value


def _provide_assets(cfg: dict[str, Any]) -> tuple[Path, Path]:
    """Every mesh of the configured object set and the hand, fetched as the rules fetch them."""
    from graspstab.assets.hand import fetch_hand_description, read_manifest
    from graspstab.assets.ycb import fetch_ycb_object

    assets = cfg["assets"]
    ycb_root = RESOURCES / "ycb"
    hand_dest = RESOURCES / "orcahand_description"
    with _assets_lock():
        for object_id, entry in cfg["objects"]["items"].items():
            dest = ycb_root / object_id
            fetched = (dest / "textured.obj").is_file() and entry.get("mesh") is None
            if fetched and _recorded(dest, "expected_sha256", entry.get("sha256")):
                continue  # fetched and verified before (the rule's outputs exist)
            fetch_ycb_object(
                object_id,
                dest,
                local_dir=assets["ycb_dir"],
                url_template=assets["ycb_url"],
                sha256=entry.get("sha256"),
                mesh_override=entry.get("mesh"),
            )
        in_place = assets["hand_dir"] and Path(assets["hand_dir"]).resolve() == hand_dest
        if not in_place and not _recorded(hand_dest, "upstream_commit", assets["hand_commit"]):
            manifest = assets["hand_manifest"]
            fetch_hand_description(
                hand_dest,
                local_dir=assets["hand_dir"],
                url_template=assets["hand_url"],
                commit=assets["hand_commit"],
                manifest=read_manifest(manifest) if manifest else None,
            )
    return ycb_root, hand_dest


@pytest.fixture(scope="session")
def resolved_assets(pytestconfig: pytest.Config) -> tuple[Path, Path]:
    """(YCB folder laid out <id>/textured.obj, hand description folder), obtained once.

    On failure every test that needs them errors with one message naming the variables to set.
    """
    from graspstab.assets import AssetError
    from graspstab.config import ConfigError

    try:
        return _provide_assets(workflow_config(pytestconfig))
    except (AssetError, ConfigError, OSError, ValueError) as exc:
        cause = str(exc)
    # outside the except block, so pytest prints this message alone (no exception chain)
    pytest.fail(
        f"graspstab tests need the YCB meshes and the ORCA hand description, obtained as the "
        f"workflow obtains them, and could not get them: {cause}\n{ASSET_HELP}",
        pytrace=False,
    )


@pytest.fixture(scope="session")
def ycb_dir(resolved_assets: tuple[Path, Path]) -> Path:
    """The YCB meshes of the default object set, laid out ``<dir>/<id>/textured.obj``."""
    return resolved_assets[0]


@pytest.fixture(scope="session")
def hand_assets_dir(resolved_assets: tuple[Path, Path]) -> Path:
    """The ORCA hand description (the folder holding ``v2/`` and ``LICENSE``)."""
    return resolved_assets[1]


@pytest.fixture(scope="session")
def foam_brick_mesh(ycb_dir: Path) -> Path:
    """The foam brick's textured.obj (the objects tests' real mesh)."""
    return ycb_dir / "061_foam_brick" / "textured.obj"


@pytest.fixture(scope="session")
def asset_env(resolved_assets: tuple[Path, Path]) -> dict[str, str]:
    """The environment for a Snakemake run that executes jobs: the variables at the assets."""
    ycb, hand = resolved_assets
    return dict(os.environ, GRASPSTAB_YCB_DIR=str(ycb), GRASPSTAB_HAND_DIR=str(hand))


@pytest.fixture(scope="session")
def bare_env() -> dict[str, str]:
    """The environment for a dry run, which needs no assets: no asset variables at all."""
    return {k: v for k, v in os.environ.items() if k not in ASSET_VARIABLES}


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
def run(tmp_path_factory, asset_env):
    """The end-to-end toy run (tests/toy_workflow.py), shared by test_workflow and test_report:
    (workdir, env, config); built once per session, whichever xdist worker asks first."""
    from tests.toy_workflow import shared_toy_run

    return shared_toy_run(tmp_path_factory, asset_env)
