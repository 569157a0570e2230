"""The one exception type for bad configuration, so the workflow stops with a readable message."""

from graspstab.common.errors import GraspstabError
from graspstab.config.credentials import mask_text


class ConfigError(ValueError, GraspstabError):
    """A configuration value is wrong; the message names the entry, the field and the fix. A
    password in a URL the message quotes is shown as ``***`` (the message reaches the terminal,
    Snakemake's log and CI logs)."""

    def __init__(self, message: str) -> None:
        super().__init__(mask_text(str(message)))
