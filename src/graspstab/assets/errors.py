"""One exception type for an input that cannot be obtained, so a job stops with a clear message."""

from __future__ import annotations

import re

from graspstab.common.errors import GraspstabError

YCB_LOCAL_HINT = (
    "To use a local copy instead, set config key assets.ycb_dir (or env var GRASPSTAB_YCB_DIR) "
    "to a directory laid out <dir>/<id>/textured.obj."
)
HAND_LOCAL_HINT = (
    "To use a local copy instead, set config key assets.hand_dir (or env var GRASPSTAB_HAND_DIR) "
    "to an orcahand_description directory (with v2/ and LICENSE)."
)

_SHA_RE = re.compile(r"^[0-9a-f]{64}$")


class AssetError(RuntimeError, GraspstabError):
    """An input file could not be provided; the message names the asset, the cause and the fix."""


def normalise_sha256(value: str | None, what: str) -> str | None:
    """Lower-case a configured sha256 and reject anything that is not 64 hex digits."""
    if value is None:
        return None
    sha = str(value).strip().lower()
    if not _SHA_RE.match(sha):
        raise AssetError(
            f"{what}: sha256 {value!r} is not 64 hexadecimal digits; fix the config value"
        )
    return sha
