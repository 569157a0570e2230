"""Configuration: compose the Hydra tree once, validate it, and hand each stage its slice."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from graspstab.config.compose import compose_config, split_snakemake_config
from graspstab.config.errors import ConfigError
from graspstab.config.validate import validate_config

__all__ = [
    "ConfigError",
    "creep_free_seeds",
    "shards_of",
    "compose_config",
    "load_config",
    "split_snakemake_config",
    "validate_config",
]


def load_config(
    config_dir: str | Path,
    schema_path: str | Path,
    snakemake_config: dict[str, Any] | None = None,
    check_files: bool = True,
) -> dict[str, Any]:
    """Compose the tree with the user's ``--config``, resolve and validate it (Snakefile's job)."""
    overrides, values = split_snakemake_config(snakemake_config or {}, config_dir)
    cfg = compose_config(config_dir, overrides, values)
    validate_config(cfg, schema_path, check_files=check_files)
    return cfg


def shards_of(config: dict[str, Any], object_id: str) -> int:
    """Annealing shards of one object: ``synthesis.shards``, or its split's entry in
    ``synthesis.split_shards`` (validation and test hold two objects each against eight in
    training, so a small run can give them more grasps per object)."""
    split = config["objects"]["items"][object_id]["split"]
    syn = config["synthesis"]
    return int((syn.get("split_shards") or {}).get(split) or syn["shards"])


def creep_free_seeds(config: dict[str, Any], study: str) -> list[int]:
    """The creep-free benchmark's training seeds for ``study`` ('train' or 'sweep'):
    ``creep_free.seeds``, else the main run's ``train.seeds`` or ``sweep.seeds``."""
    return list(config["creep_free"]["seeds"] or config[study]["seeds"])
