"""Validation of the resolved config: object-set checks that name the entry, then the schema."""

from __future__ import annotations

import difflib
import re
from pathlib import Path
from typing import Any

import jsonschema
import yaml

from graspstab.assets.catalogue import is_known_ycb_id
from graspstab.assets.errors import AssetError
from graspstab.assets.local_ycb import check_local_ycb_dir
from graspstab.config.credentials import check_storage
from graspstab.config.errors import ConfigError
from graspstab.config.relations import check_finite, check_relations

SPLITS = ("train", "val", "test")
# The object id rule when no schema is given (the schema's objects.items propertyNames pattern is
# the one in force): the workflow's {object} wildcard and every results/<stage>/<id>/ folder.
ID_PATTERN = r"^[0-9]{3}(-[a-z])?_[a-z0-9_]+$"
ID_RULE = (
    "three digits, optionally '-' and a lowercase letter, '_', then lowercase letters, digits "
    "and underscores (YCB's pattern, e.g. 014_lemon; your own mesh too, e.g. 900_my_cup)"
)
ENTRY_KEYS = ("split", "mass", "shape", "sha256", "mesh", "rotation_deg")


def load_schema(schema_path: str | Path) -> dict[str, Any]:
    """Read the YAML/JSON schema file (with libyaml's safe loader where PyYAML has it)."""
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    return yaml.load(Path(schema_path).read_text(), Loader=loader)


def _path_str(path: Any) -> str:
    return ".".join(str(p) for p in path) or "<root>"


def did_you_mean(key: str, known: Any) -> str:
    """`` (did you mean 'mass'?)`` for the closest of ``known`` to ``key``, else ``""``."""
    close = difflib.get_close_matches(str(key), [str(k) for k in known], n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _schema_message(error: jsonschema.ValidationError) -> str:
    """The schema's message, an unknown key's with the closest known key and the valid ones."""
    if error.validator == "additionalProperties" and isinstance(error.instance, dict):
        known = list(error.schema.get("properties") or {})
        extra = [k for k in error.instance if k not in known]
        if known and extra:
            return "; ".join(f"unknown key {k!r}{did_you_mean(k, known)}" for k in extra) + (
                f"; the keys here are {', '.join(known)}"
            )
    return error.message


def validate_schema(
    cfg: dict[str, Any], schema_path: str | Path, schema: dict[str, Any] | None = None
) -> None:
    """Check ``cfg`` against the schema (``schema``, the file's content when already read);
    report every violation with its dotted key."""
    schema = load_schema(schema_path) if schema is None else schema
    validator = jsonschema.Draft202012Validator(schema)
    errors = sorted(validator.iter_errors(cfg), key=lambda e: list(e.absolute_path))
    if errors:
        lines = [f"  - {_path_str(e.absolute_path)}: {_schema_message(e)}" for e in errors[:20]]
        raise ConfigError(
            f"the configuration does not match {schema_path}:\n"
            + "\n".join(lines)
            + "\nFix the value in config/ or in your --config override."
        )


def object_entry_schema(schema: dict[str, Any]) -> tuple[str, tuple[str, ...]]:
    """The object id pattern and an entry's keys, as the schema gives them."""
    items = schema["properties"]["objects"]["properties"]["items"]
    return items["propertyNames"]["pattern"], tuple(items["additionalProperties"]["properties"])


def _id_suggestion(object_id: str) -> str:
    """A name that follows the id rule, made from ``object_id`` (lowercase, other characters as
    '_', a 900 prefix when it has no three-digit one)."""
    name = re.sub(r"[^a-z0-9_]+", "_", str(object_id).lower()).strip("_") or "object"
    if re.match(r"^[0-9]{3}_", name) and re.fullmatch(ID_PATTERN, name):
        return name
    return f"900_{name}"


def validate_objects(
    cfg: dict[str, Any],
    check_files: bool = True,
    id_pattern: str = ID_PATTERN,
    entry_keys: tuple[str, ...] = ENTRY_KEYS,
) -> None:
    """Object-set checks: an id that follows the id rule, only known keys, a known YCB id (or a
    mesh), a mesh that exists, a valid split, a positive mass."""
    objects = cfg.get("objects", {})
    set_name = objects.get("name", "?")
    items = objects.get("items") or {}
    if not items:
        raise ConfigError(
            f"object set '{set_name}' has no objects (config/objects/{set_name}.yaml)"
        )
    for object_id, entry in items.items():
        where = f"object '{object_id}' in object set '{set_name}' (config/objects/{set_name}.yaml)"
        if not re.fullmatch(id_pattern, str(object_id)):
            raise ConfigError(
                f"{where}, field 'id' (the key under objects.items): {str(object_id)!r} does not "
                f"follow the object id rule {id_pattern}: {ID_RULE}. The id names the object's "
                "folders under results/ and the workflow's object wildcard. Rename the entry, "
                f"e.g. to {_id_suggestion(object_id)!r}"
            )
        if not isinstance(entry, dict):
            raise ConfigError(f"{where}: the entry must be a mapping with split, mass and sha256")
        unknown = [k for k in entry if k not in entry_keys]
        if unknown:
            key = unknown[0]
            raise ConfigError(
                f"{where}: unknown key {key!r}{did_you_mean(key, entry_keys)} in the entry "
                f"(objects.items.{object_id}.{key}); an entry's keys are {', '.join(entry_keys)}. "
                "Fix the key's spelling"
            )
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
    if check_files:  # only the objects the run covers: one left out by only_objects may be absent
        try:
            check_local_ycb_dir(items, cfg.get("assets", {}).get("ycb_dir"), only)
        except AssetError as exc:
            raise ConfigError(
                f"object set '{set_name}' (config/objects/{set_name}.yaml): {exc}"
            ) from None


def validate_config(cfg: dict[str, Any], schema_path: str | Path, check_files: bool = True) -> None:
    """Full load-time validation of the resolved configuration: no password in ``tune.storage``
    (masked in the message), the object set (its messages name the entry and field), then finite
    numbers and types (the schema), then relations between fields, which assume the types."""
    check_storage(cfg)
    schema = load_schema(schema_path)
    id_pattern, entry_keys = object_entry_schema(schema)
    validate_objects(cfg, check_files=check_files, id_pattern=id_pattern, entry_keys=entry_keys)
    check_finite(cfg)
    validate_schema(cfg, schema_path, schema)
    check_relations(cfg)
