"""The official YCB object ids, so a typo in an object set is caught at config load time."""

from __future__ import annotations

import string


def _lettered(number: str, name: str, last: str) -> list[str]:
    """Ids of a multi-part YCB object, e.g. 065-a_cups ... 065-j_cups."""
    letters = string.ascii_lowercase[: string.ascii_lowercase.index(last) + 1]
    return [f"{number}-{letter}_{name}" for letter in letters]


# As listed by the YCB benchmark site's objects.json (the list its download script reads). The site
# spells the skillet "027-skillet"; the regular spelling "027_skillet" is accepted as well.
YCB_IDS: frozenset[str] = frozenset(
    [
        "001_chips_can",
        "002_master_chef_can",
        "003_cracker_box",
        "004_sugar_box",
        "005_tomato_soup_can",
        "006_mustard_bottle",
        "007_tuna_fish_can",
        "008_pudding_box",
        "009_gelatin_box",
        "010_potted_meat_can",
        "011_banana",
        "012_strawberry",
        "013_apple",
        "014_lemon",
        "015_peach",
        "016_pear",
        "017_orange",
        "018_plum",
        "019_pitcher_base",
        "021_bleach_cleanser",
        "022_windex_bottle",
        "023_wine_glass",
        "024_bowl",
        "025_mug",
        "026_sponge",
        "027-skillet",
        "027_skillet",
        "028_skillet_lid",
        "029_plate",
        "030_fork",
        "031_spoon",
        "032_knife",
        "033_spatula",
        "035_power_drill",
        "036_wood_block",
        "037_scissors",
        "038_padlock",
        "039_key",
        "040_large_marker",
        "041_small_marker",
        "042_adjustable_wrench",
        "043_phillips_screwdriver",
        "044_flat_screwdriver",
        "046_plastic_bolt",
        "047_plastic_nut",
        "048_hammer",
        "049_small_clamp",
        "050_medium_clamp",
        "051_large_clamp",
        "052_extra_large_clamp",
        "053_mini_soccer_ball",
        "054_softball",
        "055_baseball",
        "056_tennis_ball",
        "057_racquetball",
        "058_golf_ball",
        "059_chain",
        "061_foam_brick",
        "062_dice",
        *_lettered("063", "marbles", "f"),
        *_lettered("065", "cups", "j"),
        *_lettered("070", "colored_wood_blocks", "b"),
        "071_nine_hole_peg_test",
        *_lettered("072", "toy_airplane", "k"),
        *_lettered("073", "lego_duplo", "m"),
        "076_timer",
        "077_rubiks_cube",
    ]
)


def is_known_ycb_id(object_id: str) -> bool:
    """True when ``object_id`` is an official YCB object id."""
    return object_id in YCB_IDS
