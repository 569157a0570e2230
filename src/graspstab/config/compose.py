"""Hydra composition (compose API) and translation of ``snakemake --config`` into overrides.

Snakemake accepts only undotted ``--config`` keys and parses nested values with YAML's BaseLoader
(every leaf a string), and Hydra's override grammar rejects keys that start with a digit (YCB ids
such as ``014_lemon``). So group choices (``profile=thesis``) and raw override strings
(``overrides=[synthesis.shards=3]``) go to Hydra, while every other value
(``'synthesis={shards: 3}'``, ``seed=7``) is merged into the composed config with OmegaConf, whose
struct mode still rejects unknown keys.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from hydra import compose, initialize_config_dir
from hydra.errors import HydraException
from omegaconf import OmegaConf
from omegaconf.errors import OmegaConfBaseException

from graspstab.config.errors import ConfigError

RAW_OVERRIDES_KEY = "overrides"


def _coerce(value: Any) -> Any:
    """Undo BaseLoader's all-strings parsing: '3' -> 3, '0.1' -> 0.1, 'null' -> None."""
    if isinstance(value, dict):
        return {k: _coerce(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_coerce(v) for v in value]
    if isinstance(value, str) and value.strip():
        parsed = yaml.safe_load(value)
        if isinstance(parsed, bool | int | float) or parsed is None:
            return parsed
    return value


def config_groups(config_dir: str | Path) -> set[str]:
    """Names of the Hydra config groups (sub-directories of the config tree)."""
    return {p.name for p in Path(config_dir).iterdir() if p.is_dir()}


def split_snakemake_config(
    snakemake_config: dict[str, Any], config_dir: str | Path
) -> tuple[list[str], dict[str, Any]]:
    """Split ``--config`` into Hydra overrides (group choices, raw strings) and values to merge."""
    groups = config_groups(config_dir)
    overrides: list[str] = []
    values: dict[str, Any] = {}
    for key, value in snakemake_config.items():
        if key == RAW_OVERRIDES_KEY:
            overrides.extend(str(v) for v in (value if isinstance(value, list) else [value]))
        elif key in groups and isinstance(value, str):
            overrides.append(f"{key}={value}")
        else:
            values[key] = _coerce(value)
    return overrides, values


def compose_config(
    config_dir: str | Path,
    overrides: list[str] | None = None,
    values: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Compose ``config_dir/config.yaml`` with Hydra ``overrides``, merge ``values``, resolve."""
    config_dir = Path(config_dir).resolve()
    if not (config_dir / "config.yaml").is_file():
        raise ConfigError(f"no config.yaml in {config_dir}: point the workflow at the config/ tree")
    overrides = list(overrides or [])
    try:
        with initialize_config_dir(config_dir=str(config_dir), version_base="1.3"):
            cfg = compose(config_name="config", overrides=overrides)
    except yaml.YAMLError as exc:
        hint = (
            " An id (or key) appears twice in that file: each object id must appear once in "
            "its object set; remove or rename one entry."
            if "duplicate key" in str(exc)
            else " Fix the YAML syntax at the line shown."
        )
        where = f"could not read a file of the config tree {config_dir}"
        raise ConfigError(f"{where}: {exc}.{hint}") from exc
    except (HydraException, OmegaConfBaseException) as exc:
        raise ConfigError(
            f"could not compose the configuration in {config_dir} with overrides {overrides}: {exc}"
        ) from exc
    try:
        if values:
            cfg = OmegaConf.merge(cfg, OmegaConf.create(values))
        resolved = OmegaConf.to_container(cfg, resolve=True)
    except OmegaConfBaseException as exc:
        raise ConfigError(
            f"could not apply the --config values {values}: {exc}. Check the key names against "
            f"the files in {config_dir}."
        ) from exc
    assert isinstance(resolved, dict)
    return resolved
