"""MJCF names of the ORCA v2 right hand, resolved once here so every module agrees on them."""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from graspstab.common.errors import GraspstabError

FINGERS: tuple[str, ...] = ("thumb", "index", "middle", "ring", "little")

# Root body and free joint added by the hand stage (3.1.1: the wrist is a free pose).
ROOT_BODY = "hand_root"
WRIST_JOINT = "wrist"

PALM_BODY = "right_R-Carpals_8d1f1041"
DROP_BODIES: tuple[str, ...] = (
    "right_tower",
    "right_ForeArmStructure-Model_e18f2368",
    "right_TopTower-Model_4a80d30e",
)
DROP_JOINTS: tuple[str, ...] = ("right_wrist",)

# Palm collision mesh: always the hard core, whichever layout the description comes in.
PALM_CORE_STL = "R-Carpals_CORE.stl"
PALM_SKIN_STL = "R-Carpals_Skin.stl"
PALM_SKIN_MESH = "right_R-Carpals_Skin"

JOINTS_BY_FINGER: dict[str, tuple[str, ...]] = {
    "thumb": ("right_t-cmc", "right_t-abd", "right_t-mcp", "right_t-pip"),
    "index": ("right_i-abd", "right_i-mcp", "right_i-pip"),
    "middle": ("right_m-abd", "right_m-mcp", "right_m-pip"),
    "ring": ("right_r-abd", "right_r-mcp", "right_r-pip"),
    "little": ("right_p-abd", "right_p-mcp", "right_p-pip"),
}
# Canonical order of the 16 finger joints (by finger, thumb first): theta in g = (P, R, theta).
FINGER_JOINTS: tuple[str, ...] = tuple(j for f in FINGERS for j in JOINTS_BY_FINGER[f])

FINGERTIP_BODIES: dict[str, str] = {
    "thumb": "right_T-DP_b7429e50",
    "index": "right_I-FingerTipAssembly_ec49c16c",
    "middle": "right_M-FingerTipAssembly_34afb748",
    "ring": "right_M-FingerTipAssembly_424a8e75",  # the ring finger reuses the middle's parts
    "little": "right_P-FingerTipAssembly_cd219176",
}
PROXIMAL_BODIES: dict[str, str] = {
    "thumb": "right_T-PP_68395e98",
    "index": "right_I-PP_bacbd481",
    "middle": "right_M-PP_08efa608",
    "ring": "right_M-PP_8660a1eb",
    "little": "right_P-PP_1d411b9b",
}
# Every finger link with a collision mesh, palm side first (thumb: T-TP-R, R-T-AP, T-PP, T-DP).
FINGER_LINK_BODIES: dict[str, tuple[str, ...]] = {
    "thumb": (
        "right_T-TP-R_1c2b802d",
        "right_R-T-AP_a9723101",
        PROXIMAL_BODIES["thumb"],
        FINGERTIP_BODIES["thumb"],
    ),
    "index": ("right_I-AP-R_d95d02d1", PROXIMAL_BODIES["index"], FINGERTIP_BODIES["index"]),
    "middle": ("right_M-AP_e04a96f2", PROXIMAL_BODIES["middle"], FINGERTIP_BODIES["middle"]),
    "ring": ("right_M-AP_6ec59111", PROXIMAL_BODIES["ring"], FINGERTIP_BODIES["ring"]),
    "little": ("right_P-AP_f5e42b61", PROXIMAL_BODIES["little"], FINGERTIP_BODIES["little"]),
}


class HandNameError(KeyError, GraspstabError):
    """A configured MJCF name is not in the hand description; the message lists the valid ones."""

    def __str__(self) -> str:  # KeyError quotes its message; show it plainly
        return str(self.args[0]) if self.args else ""


def require_name(name: str, valid: Iterable[str], what: str, where: str = "") -> str:
    """Return ``name`` if it is among ``valid``, else raise an error that lists the valid names."""
    valid = list(valid)
    if name not in valid:
        place = f" in {where}" if where else ""
        raise HandNameError(
            f"{what} {name!r} not found{place}; valid names: {', '.join(sorted(valid))}. "
            "Fix the hand config (config/hand/*.yaml) to use one of them."
        )
    return name


def require_fingers(mapping: Mapping[str, object], what: str) -> None:
    """Check that a per-finger mapping names exactly the five fingers."""
    if set(mapping) != set(FINGERS):
        raise HandNameError(
            f"{what} must have exactly the fingers {', '.join(FINGERS)}; got {', '.join(mapping)}"
        )
