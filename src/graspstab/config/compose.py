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
from omegaconf.errors import ConfigKeyError, OmegaConfBaseException

from graspstab.config.errors import ConfigError

RAW_OVERRIDES_KEY = "overrides"


def _coerce(value: Any) -> Any:
    """Undo BaseLoader's all-strings parsing: '3' -> 3, '0.1' -> 0.1, 'null' -> None."""
    if isinstance(value, dict):
        return {k: _coerce(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_coerce(v) for v in value]
    if isinstance(value, str) and value.strip():
        try:
            parsed = yaml.safe_load(value)
        except yaml.YAMLError:  # not a YAML scalar ('[1', 'a: b: c'): the string as given
            return value
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


def _unknown_key_message(exc: ConfigKeyError, config_dir: Path, set_name: Any) -> str:
    """A ``--config`` value under a key the composed tree lacks: the dotted key, the closest
    known key and the known ones, or, under ``objects.items``, how objects are added."""
    from graspstab.config.validate import ENTRY_KEYS, did_you_mean  # validate imports compose

    key, full = str(exc.key), str(exc.full_key)
    parent = full.rsplit(".", 1)[0] if "." in full else "the top level"
    node = exc.parent_node
    known = [str(k) for k in node.keys()] if node is not None and hasattr(node, "keys") else []
    set_file = f"config/objects/{set_name}.yaml in {config_dir}"
    if full == f"objects.items.{key}":
        close = did_you_mean(key, known)
        return (
            f"--config names object {key!r} under objects.items, which is not in object set "
            f"{set_name!r}{close}: --config can change the fields of an object the set holds, "
            f"not add one. Add it to an object set file ({set_file}, or a set of your own beside "
            'it; README "Add an object")'
        )
    in_entry = full.startswith("objects.items.") and full.count(".") == 3
    if in_entry and key in ENTRY_KEYS:
        return (
            f"--config sets {full}, but that entry of object set {set_name!r} has no {key!r}: "
            "--config can change only the fields an entry already has. Add the field to the "
            f"entry in its object set file ({set_file})"
        )
    if in_entry:
        known = list(ENTRY_KEYS)
    listed = f"; the keys there are {', '.join(known)}" if known else ""
    return (
        f"unknown key {key!r}{did_you_mean(key, known)} at {parent} in your --config values "
        f"({full}){listed}. Fix the key's spelling"
    )


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
    except ConfigKeyError as exc:
        set_name = OmegaConf.select(cfg, "objects.name", default="?")
        raise ConfigError(_unknown_key_message(exc, config_dir, set_name)) from exc
    except OmegaConfBaseException as exc:
        raise ConfigError(
            f"could not apply the --config values {values}: {exc}. Check the key names against "
            f"the files in {config_dir}."
        ) from exc
    assert isinstance(resolved, dict)
    return resolved
