"""Validation of the resolved config: object-set checks that name the entry, then the schema."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import jsonschema
import yaml

from graspstab.assets.catalogue import is_known_ycb_id
from graspstab.config.errors import ConfigError
from graspstab.config.relations import check_finite, check_relations

SPLITS = ("train", "val", "test")


def load_schema(schema_path: str | Path) -> dict[str, Any]:
    """Read the YAML/JSON schema file."""
    return yaml.safe_load(Path(schema_path).read_text())


def _path_str(path: Any) -> str:
    return ".".join(str(p) for p in path) or "<root>"


def validate_schema(cfg: dict[str, Any], schema_path: str | Path) -> None:
    """Check ``cfg`` against the schema; report every violation with its dotted key."""
    schema = load_schema(schema_path)
    validator = jsonschema.Draft202012Validator(schema)
    errors = sorted(validator.iter_errors(cfg), key=lambda e: list(e.absolute_path))
    if errors:
        lines = [f"  - {_path_str(e.absolute_path)}: {e.message}" for e in errors[:20]]
        raise ConfigError(
            f"the configuration does not match {schema_path}:\n"
            + "\n".join(lines)
            + "\nFix the value in config/ or in your --config override."
        )


def validate_objects(cfg: dict[str, Any], check_files: bool = True) -> None:
    """Object-set checks: known YCB id, a mesh that exists, a valid split, a positive mass."""
    objects = cfg.get("objects", {})
    set_name = objects.get("name", "?")
    items = objects.get("items") or {}
    if not items:
        raise ConfigError(
            f"object set '{set_name}' has no objects (config/objects/{set_name}.yaml)"
        )
    ycb_dir = cfg.get("assets", {}).get("ycb_dir")
    for object_id, entry in items.items():
        where = f"object '{object_id}' in object set '{set_name}' (config/objects/{set_name}.yaml)"
        if not isinstance(entry, dict):
            raise ConfigError(f"{where}: the entry must be a mapping with split, mass and sha256")
        mesh = entry.get("mesh")
        if mesh is None and not is_known_ycb_id(object_id):
            raise ConfigError(
                f"{where}, field 'id': '{object_id}' is not a YCB object id "
                "(e.g. 061_foam_brick); fix the id or give your own mesh in field 'mesh'"
            )
        split = entry.get("split")
        if split not in SPLITS:
            raise ConfigError(
                f"{where}, field 'split': {split!r} is not one of {', '.join(SPLITS)}"
            )
        mass = entry.get("mass")
        if isinstance(mass, bool) or not isinstance(mass, int | float) or not mass > 0:
            raise ConfigError(
                f"{where}, field 'mass': {mass!r} must be a positive number of kilograms"
            )
        if not check_files:
            continue
        if mesh is not None:
            if not Path(mesh).is_file():
                raise ConfigError(f"{where}, field 'mesh': no such file {mesh}")
            if Path(mesh).suffix.lower() != ".obj":
                raise ConfigError(
                    f"{where}, field 'mesh': {mesh} is not a Wavefront OBJ file (suffix "
                    f"'{Path(mesh).suffix}'); graspstab reads OBJ meshes in metres only: convert "
                    "it (e.g. trimesh.load(path).export('mesh.obj')) and give the .obj file"
                )
        elif ycb_dir is not None:
            path = Path(ycb_dir) / object_id / "textured.obj"
            if not path.is_file():
                raise ConfigError(
                    f"{where}, field 'mesh': {path} does not exist; the local YCB directory "
                    f"(assets.ycb_dir / GRASPSTAB_YCB_DIR = {ycb_dir}) must hold "
                    "<id>/textured.obj, or unset it to download the official archive"
                )
    only = cfg.get("only_objects")
    if only is not None and not isinstance(only, list):
        raise ConfigError(
            f"only_objects = {only!r} must be a list of object ids, e.g. "
            f"--config 'only_objects=[{only}]' (a bare string would be read letter by letter)"
        )
    if only is not None:
        unknown = [o for o in only if o not in items]
        if unknown:
            raise ConfigError(
                f"only_objects names {unknown}, which are not in object set '{set_name}'; "
                f"valid ids: {', '.join(items)}"
            )


def validate_config(cfg: dict[str, Any], schema_path: str | Path, check_files: bool = True) -> None:
    """Full load-time validation of the resolved configuration: the object set (its messages name
    the entry and field), then finite numbers and types (the schema), then relations between
    fields, which assume the types."""
    validate_objects(cfg, check_files=check_files)
    check_finite(cfg)
    validate_schema(cfg, schema_path)
    check_relations(cfg)
