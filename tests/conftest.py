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
