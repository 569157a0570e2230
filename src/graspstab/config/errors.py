"""The one exception type for bad configuration, so the workflow stops with a readable message."""


class ConfigError(ValueError):
    """A configuration value is wrong; the message names the entry, the field and the fix."""
