"""Workflow inputs (YCB meshes, ORCA hand model) from a local copy or a checksummed download."""

from graspstab.assets.catalogue import YCB_IDS, is_known_ycb_id
from graspstab.assets.errors import AssetError
from graspstab.assets.hand import fetch_hand_description
from graspstab.assets.ycb import fetch_ycb_object

__all__ = [
    "YCB_IDS",
    "AssetError",
    "fetch_hand_description",
    "fetch_ycb_object",
    "is_known_ycb_id",
]
