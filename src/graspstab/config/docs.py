"""The configuration reference page (docs/configuration.md), generated from config/ and the schema.

Every key of the composed default configuration (the quick profile) gets a row: its type and
allowed values from the schema, its default, and a description taken from the comment beside it in
its group's YAML file (else from the same field of another use of a shared schema definition, else
from the schema's ``description``). Keys the schema allows but the default leaves unset get rows
too. The group options and their file headers follow the files. Each profile's values are its
composition (``profile=<name>``, so its ``defaults`` list, another profile or a group option,
applies as in a run) against the composition without a profile. Nothing is resolved, so the page
does not depend on the environment (``${oc.env:...}`` values are shown as the variable and its
fallback).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from hydra import compose, initialize_config_dir
from hydra.errors import HydraException
from omegaconf import OmegaConf
from omegaconf.errors import OmegaConfBaseException

from graspstab.config.errors import ConfigError
from graspstab.config.validate import load_schema

COMMAND = "python -m graspstab.config.docs > docs/configuration.md"
MISSING: Any = object()
NO_DESCRIPTION = "*No description yet.*"
# A group option a profile chooses that changes more keys than this (an object set) gets one
# row saying how many, not a row per key.
MAX_GROUP_ROWS = 12
# Keys whose natural places (a comment beside them in config/config.yaml, or a schema description
# in the schema's assets block) are being edited elsewhere; a comment there takes precedence.
_ENV = re.compile(r"^\$\{oc\.env:(?P<var>\w+),(?P<default>[^}]*)\}$")
_KEY = re.compile(
    r"^(?P<indent>\s*)(?:-\s+)?"
    r"(?P<key>\"[^\"]*\"|'[^']*'|[^\s#:'\"{}\[\],-][^#:{}\[\],]*?)\s*:(?:\s+|$)(?P<rest>.*)$"
)


# Comments of one YAML file, by dotted key.


def _split_comment(text: str) -> tuple[str, str | None, int]:
    """``(code, comment, column of '#')`` of one line; a '#' in quotes or inside a word is code."""
    quote = None
    for i, ch in enumerate(text):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or text[i - 1].isspace()):
            return text[:i], text[i + 1 :].strip(), i
    return text, None, -1


def _depth(code: str) -> int:
    """Open minus closed flow brackets (quoted text ignored)."""
    code = re.sub(r"\"[^\"]*\"|'[^']*'", "", code)
    return sum(code.count(c) for c in "{[") - sum(code.count(c) for c in "}]")


@dataclass
class YamlComments:
    """A YAML file's leading comment block and the comment text beside or above each key."""

    package: str | None
    header: str
    keys: dict[str, str]


def scan_comments(path: Path) -> YamlComments:
    """Comments by dotted key: the one on the key's line (continued on following lines at the
    same column, or on the lines of a flow collection it opens), then the block just above it
    (a blank line ends a block). The file's first block is its header, not its first key's."""
    package = None
    header: list[str] = []
    beside: dict[str, list[str]] = {}
    above: dict[str, list[str]] = {}
    stack: list[tuple[int, str]] = []
    pending: list[str] = []
    last: tuple[str, int] | None = None  # the last comment beside a key: (key, its column)
    current: str | None = None
    depth = 0
    for line in path.read_text().splitlines():
        stripped = line.strip()
        if depth > 0 and current is not None:  # inside a flow collection spanning lines
            code, comment, _ = _split_comment(line)
            depth += _depth(code)
            if comment:
                beside.setdefault(current, []).append(comment)
            continue
        if not stripped:
            if current is None and pending and not header:
                header, pending = pending, []
            pending, last = [], None
            continue
        if stripped.startswith("#"):
            text = stripped[1:].strip()
            if text.startswith("@package"):
                package = text.split(None, 1)[1].strip()
            elif last is not None and line.index("#") == last[1]:
                beside[last[0]].append(text)
            else:
                pending.append(text)
                last = None
            continue
        m = _KEY.match(line)
        if m is None:
            continue
        if current is None and not header:
            header, pending = pending, []
        indent = m.start("key")
        while stack and stack[-1][0] >= indent:
            stack.pop()
        key = m["key"].strip("\"'")
        current = ".".join([k for _, k in stack] + [key])
        code, comment, col = _split_comment(m["rest"])
        beside[current] = [comment] if comment else []
        above[current], pending = pending, []
        last = (current, m.start("rest") + col) if comment else None
        stack.append((indent, key))
        depth = _depth(code)
    keys = {}
    for key in beside:
        parts = [" ".join(p) for p in (beside[key], above.get(key, [])) if p]
        if parts:
            keys[key] = parts[0] if len(parts) == 1 else _join(*parts)
    return YamlComments(package, " ".join(header), keys)


def _join(first: str, second: str) -> str:
    """The comment beside a key and the block above it, as one text."""
    return first + (" " if first[-1:] in ".;:" else "; ") + second


# Composition without resolution.


def compose_raw(config_dir: Path, overrides: list[str]) -> tuple[dict[str, Any], dict[str, Any]]:
    """The composed tree with interpolations kept, and Hydra's group choices."""
    try:
        with initialize_config_dir(config_dir=str(config_dir), version_base="1.3"):
            cfg = compose(config_name="config", overrides=overrides, return_hydra_config=True)
        choices = dict(cfg.hydra.runtime.choices)
        tree = OmegaConf.to_container(cfg, resolve=False)
    except (HydraException, OmegaConfBaseException, yaml.YAMLError) as exc:
        raise ConfigError(f"could not compose {config_dir} with {overrides}: {exc}") from exc
    assert isinstance(tree, dict)
    tree.pop("hydra")
    return tree, {k: v for k, v in choices.items() if not k.startswith("hydra/")}


def get(tree: Any, path: str) -> Any:
    """The value at dotted ``path``, or MISSING."""
    for part in path.split("."):
        if not isinstance(tree, dict) or part not in tree:
            return MISSING
        tree = tree[part]
    return tree


def leaves(tree: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Dotted path -> value of every non-mapping value (lists are values)."""
    out: dict[str, Any] = {}
    for key, value in tree.items():
        path = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, dict) and value:
            out.update(leaves(value, path))
        else:
            out[path] = value
    return out


# Markdown.


def inline(value: Any) -> str:
    """A value as a code span of flow-style YAML; ``${oc.env:VAR,default}`` as the variable."""
    if value is MISSING:
        return "not set"
    if isinstance(value, str) and (m := _ENV.match(value)):
        return f"`${m['var']}` if set, else `{m['default'] or 'null'}`"
    text = yaml.safe_dump(
        value, default_flow_style=True, width=10**9, sort_keys=False, allow_unicode=True
    )
    return f"`{text.strip().removesuffix('...').strip()}`"


def text(s: str) -> str:
    """Comment text for a table cell: pipes and angle brackets escaped outside code spans."""
    parts = s.split("`")
    for i in range(0, len(parts), 2):
        parts[i] = parts[i].replace("|", "\\|").replace("<", "&lt;")
    return "`".join(parts)


def table(header: list[str], rows: list[list[str]]) -> list[str]:
    """A Markdown table."""
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(cell.replace("\n", " ") for cell in row) + " |" for row in rows]
    return out + [""]


# Schema.


def _fmt(v: Any) -> str:
    return str(v).lower() if isinstance(v, bool) or v is None else str(v)


def _code(v: Any) -> str:
    return "`null`" if v is None else f"`{_fmt(v)}`"


class Schema:
    """The config schema: ``$ref``s followed, types summarised for a reader."""

    def __init__(self, schema: dict[str, Any]):
        self.root = schema
        self.defs = schema.get("$defs", {})

    def resolve(self, node: dict[str, Any]) -> tuple[dict[str, Any], str | None]:
        """``node`` with its ``$ref`` merged in (sibling keywords win, sibling properties are
        merged), and the name of the object definition it came from, if any."""
        origin = None
        while "$ref" in node:
            name = node["$ref"].rsplit("/", 1)[-1]
            target = self.defs[name]
            merged = dict(target)
            for key, value in node.items():
                if key == "properties":
                    merged["properties"] = {**target.get("properties", {}), **value}
                elif key != "$ref":
                    merged[key] = value
            if origin is None and "properties" in target:
                origin = name
            node = merged
        return node, origin

    def type_of(self, node: dict[str, Any]) -> str:
        """What values ``node`` allows, in words."""
        node, _ = self.resolve(node)
        if "const" in node:
            return f"always {_code(node['const'])}"
        if "enum" in node:
            return "one of " + ", ".join(_code(v) for v in node["enum"])
        for key in ("oneOf", "anyOf"):
            if key in node:
                return " or ".join(self.type_of(n) for n in node[key])
        types = node.get("type")
        if types is None:
            types = "object" if "properties" in node else "array" if "items" in node else []
        types = [types] if isinstance(types, str) else list(types)
        words = [self._one_type(t, node) for t in types if t != "null"]
        return " or ".join(words + (["null"] if "null" in types else [])) or "any value"

    def _one_type(self, kind: str, node: dict[str, Any]) -> str:
        if kind in ("number", "integer"):
            lo = ("[", node["minimum"]) if "minimum" in node else None
            lo = ("(", node["exclusiveMinimum"]) if "exclusiveMinimum" in node else lo
            hi = ("]", node["maximum"]) if "maximum" in node else None
            hi = (")", node["exclusiveMaximum"]) if "exclusiveMaximum" in node else hi
            if lo and hi:
                return f"{kind} in {lo[0]}{_fmt(lo[1])}, {_fmt(hi[1])}{hi[0]}"
            if lo:
                return f"{kind} {'≥' if lo[0] == '[' else '>'} {_fmt(lo[1])}"
            if hi:
                return f"{kind} {'≤' if hi[0] == ']' else '<'} {_fmt(hi[1])}"
            return kind
        if kind == "string":
            if "pattern" in node:
                return f"string matching `{node['pattern']}`"
            return "non-empty string" if node.get("minLength", 0) >= 1 else "string"
        if kind == "array":
            words = "list"
            if "items" in node:
                item = self.type_of(node["items"])
                words += (
                    f" of ({item})" if " " in item and not item.startswith("`") else f" of {item}"
                )
            lo, hi = node.get("minItems"), node.get("maxItems")
            if lo is not None and lo == hi:
                words += f", exactly {lo} items"
            elif lo is not None:
                words += f", at least {lo} item{'s' * (lo != 1)}"
            if hi is not None and lo != hi:
                words += f", at most {hi} items"
            return words + (", no repeats" if node.get("uniqueItems") else "")
        if kind == "object":
            return "mapping"
        return kind


# Rows.


@dataclass
class Row:
    """One row of a section's table."""

    path: str
    type: str
    default: str
    description: str
    origin: tuple[str, str] | None = None  # (schema definition, field path inside it)


class Reference:
    """Everything the page is made of, read once from the config tree and the schema."""

    def __init__(self, config_dir: str | Path, schema_path: str | Path):
        self.config_dir = Path(config_dir).resolve()
        if not (self.config_dir / "config.yaml").is_file():
            raise ConfigError(f"no config.yaml in {self.config_dir}")
        self.schema = Schema(load_schema(schema_path))
        self.default, self.choices = compose_raw(self.config_dir, [])
        self.base, self.base_choices = compose_raw(self.config_dir, ["~profile"])
        self._composed: dict[str, tuple[dict[str, Any], dict[str, Any]]] = {}
        self.root_comments = scan_comments(self.config_dir / "config.yaml")
        self.defaults = self._defaults_list()
        self.groups = sorted(p.name for p in self.config_dir.iterdir() if p.is_dir())
        self.options = {
            g: sorted(p.stem for p in (self.config_dir / g).glob("*.yaml")) for g in self.groups
        }
        self.files = {
            (g, o): scan_comments(self.config_dir / g / f"{o}.yaml")
            for g in self.groups
            for o in self.options[g]
        }
        self.comments = self._key_comments()

    # The defaults list and where each group lands.

    def _defaults_list(self) -> list[tuple[str, str, str | None, str]]:
        """``(group, choice key, explicit package, option in config.yaml)`` of each entry."""
        data = yaml.safe_load((self.config_dir / "config.yaml").read_text())
        out = []
        for entry in data.get("defaults", []):
            if isinstance(entry, dict):
                ((key, option),) = entry.items()
                group, _, package = key.partition("@")
                out.append((group, key, package or None, option))
        return out

    def package(self, group: str, explicit: str | None, option: str) -> str:
        """Where an option's keys land ('' for the top level)."""
        pkg = explicit or self.files[(group, option)].package or group
        return "" if pkg == "_global_" else pkg

    def placements(self) -> list[dict[str, Any]]:
        """Every group entry of config/config.yaml with its effective default option."""
        out = []
        for group, key, explicit, listed in self.defaults:
            chosen = self.choices.get(key, listed)
            out.append(
                {
                    "group": group,
                    "key": key,
                    "package": self.package(group, explicit, chosen),
                    "listed": listed,
                    "chosen": chosen,
                    "about": self.root_comments.keys.get(f"defaults.{key}", ""),
                }
            )
        return out

    def _key_comments(self) -> dict[str, str]:
        """Comment per dotted key: config.yaml's own keys and each group's effective option (a
        comment often explains the option's value, so other options' are not borrowed). Profile
        files explain their values, so they are not used here either."""
        out = {k: v for k, v in self.root_comments.keys.items() if not k.startswith("defaults.")}
        for place in self.placements():
            if place["group"] == "profile":
                continue
            group = place["group"]
            explicit = None if place["key"] == group else place["key"].partition("@")[2]
            option = place["chosen"]
            prefix = self.package(group, explicit, option)
            for key, comment in self.files[(group, option)].keys.items():
                out.setdefault(f"{prefix}.{key}" if prefix else key, comment)
        return out

    # Rows of one section.

    def rows(self, path: str) -> list[Row]:
        """The rows of the subtree at ``path`` (a top-level key, or '' for the scalars)."""
        rows: list[Row] = []
        if path:
            node = self.schema.root["properties"].get(path, {})
            self._walk(path, self.default[path], node, None, rows)
        else:
            for key, value in self.default.items():
                if not isinstance(value, dict):
                    self._walk(key, value, self.schema.root["properties"].get(key, {}), None, rows)
        self._fill(rows)
        return rows

    def _walk(
        self,
        path: str,
        value: Any,
        node: dict[str, Any],
        origin: tuple[str, str] | None,
        rows: list[Row],
    ) -> None:
        node, name = self.schema.resolve(node)
        if name is not None:
            origin = (name, "")
        props = node.get("properties") or {}
        extra = node.get("additionalProperties")
        is_map = isinstance(value, dict) or (value is MISSING and "properties" in node)
        if not is_map:
            rows.append(
                Row(
                    path,
                    self.schema.type_of(node),
                    self._default(path),
                    self._comment(path),
                    origin,
                )
            )
            return
        if "." in path and (comment := self._comment(path)):
            rows.append(Row(path, self.schema.type_of(node), "", comment, origin))
        if not props and isinstance(extra, dict):
            self._entries(path, value if isinstance(value, dict) else {}, node, rows)
            return
        present = list(value) if isinstance(value, dict) else []
        for key in present + [k for k in props if k not in present]:
            child = props.get(key, extra if isinstance(extra, dict) else {})
            sub = (origin[0], f"{origin[1]}.{key}".lstrip(".")) if origin else None
            got = value.get(key, MISSING) if isinstance(value, dict) else MISSING
            self._walk(f"{path}.{key}", got, child, sub, rows)

    def _entries(
        self, path: str, value: dict[str, Any], node: dict[str, Any], rows: list[Row]
    ) -> None:
        """A mapping of free names (object ids, presets, searched parameters): the entry's
        fields with a placeholder name, then one row per entry with its value."""
        entry, _ = self.schema.resolve(node["additionalProperties"])
        ph = "<id>" if "propertyNames" in node else "<name>"
        fields = entry.get("properties")
        if fields:
            required = set(entry.get("required", []))
            for field, sub in fields.items():
                seen = [f"{path}.{k}.{field}" for k, v in value.items() if field in v]
                comment = next((self.comments[p] for p in seen if p in self.comments), "")
                rows.append(
                    Row(
                        f"{path}.{ph}.{field}",
                        self.schema.type_of(sub) + ("" if field in required else " (optional)"),
                        "per entry" if seen else "not set",
                        comment or self.schema.resolve(sub)[0].get("description", ""),
                    )
                )
        else:
            about = entry.get("description", node.get("description", ""))
            rows.append(Row(f"{path}.{ph}", self.schema.type_of(entry), "", about))
        for key, item in value.items():
            rows.append(
                Row(
                    f"{path}.{key}",
                    f"`{ph}` entry",
                    inline(item),
                    self.comments.get(f"{path}.{key}", f"An entry of `{path}`."),
                )
            )

    def _comment(self, path: str) -> str:
        return self.comments.get(path, "")

    def _default(self, path: str) -> str:
        value, base = get(self.default, path), get(self.base, path)
        shown = inline(value)
        profile = self.choices.get("profile", "quick")
        if base is MISSING and value is not MISSING:
            return f"{shown} (set by the {profile} profile)"
        if base != value:
            return f"{shown} (the {profile} profile; group default {inline(base)})"
        return shown

    def _fill(self, rows: list[Row]) -> None:
        """Missing descriptions: the same field of another use of the definition, the schema's
        description, the fallbacks above."""
        by_origin = {r.origin: r.description for r in rows if r.origin and r.description}
        for other in ("model", "sweep"):  # the model specs share definitions across sections
            for r in self._shared_rows(other):
                by_origin.setdefault(r.origin, r.description)
        for row in rows:
            if row.description:
                continue
            row.description = (
                by_origin.get(row.origin, "")
                or self._schema_description(row.path)
                or NO_DESCRIPTION
            )

    def _shared_rows(self, section: str) -> list[Row]:
        rows: list[Row] = []
        if section in self.default:
            node = self.schema.root["properties"][section]
            self._walk(section, self.default[section], node, None, rows)
        return [r for r in rows if r.origin and r.description]

    def _schema_description(self, path: str) -> str:
        node: dict[str, Any] = self.schema.root
        for part in path.split("."):
            node, _ = self.schema.resolve(node)
            props = node.get("properties") or {}
            if part in props:
                node = props[part]
            elif isinstance(node.get("additionalProperties"), dict):
                node = node["additionalProperties"]
            else:
                return ""
        return self.schema.resolve(node)[0].get("description", "")

    # Profiles.

    def composed(self, profile: str) -> tuple[dict[str, Any], dict[str, Any]]:
        """The tree and group choices of ``profile=<profile>``, composed by Hydra (so a
        profile's defaults list, another profile or a group override, is applied as it runs)."""
        if profile not in self._composed:
            self._composed[profile] = compose_raw(self.config_dir, [f"profile={profile}"])
        return self._composed[profile]

    def profile_file(self, name: str) -> ProfileFile:
        """What one profile file says: its keys, the profiles and group options it lists."""
        data = yaml.safe_load((self.config_dir / "profile" / f"{name}.yaml").read_text()) or {}
        entries: list[str] = []
        overrides: dict[str, tuple[str, str]] = {}
        for entry in data.pop("defaults", None) or []:
            if isinstance(entry, str):
                entries.append(entry.removeprefix("/profile/"))
            elif isinstance(entry, dict):
                ((key, option),) = entry.items()
                group_key = key.removeprefix("override").strip().lstrip("/")
                overrides[group_key] = (key, option)
        if "_self_" not in entries:  # Hydra merges a config's own keys last unless told otherwise
            entries.append("_self_")
        return ProfileFile(name, data, entries, overrides, self.files[("profile", name)])

    def chain(self, name: str, seen: tuple[str, ...] = ()) -> list[str]:
        """The profile files ``profile=<name>`` merges, in Hydra's order (a later one wins)."""
        out: list[str] = []
        for entry in self.profile_file(name).entries:
            names = (
                [name]
                if entry == "_self_"
                else self.chain(entry, (*seen, name))
                if entry in self.options["profile"] and entry not in seen
                else []
            )
            out += [n for n in names if n not in out]
        return out

    def profile_rows(self, name: str) -> ProfileRows:
        """Every group choice and key of ``profile=<name>`` that differs from the groups' defaults
        (composed without a profile) or that one of its profile files sets, each with the file
        that sets it: the profile, one it builds on, or a group option it chooses."""
        tree, choices = self.composed(name)
        files = [self.profile_file(p) for p in reversed(self.chain(name))]  # the winner first
        rows = ProfileRows(name, [f.name for f in files if f.name != name])
        places = {p["key"]: p for p in self.placements() if p["group"] != "profile"}
        changed: dict[str, tuple[str, list[str]]] = {}  # group key -> (package, its keys)
        for key, place in places.items():
            option = choices.get(key, place["chosen"])
            setter = next((f for f in files if key in f.overrides), None)
            if option == self.base_choices.get(key) and setter is None:
                continue
            explicit = key.partition("@")[2] or None
            package = self.package(place["group"], explicit, option)
            changed[key] = (
                package,
                [package] if package else self._global_keys(place["group"], option),
            )
            source = setter.name if setter else ""
            note = ("profile", source, f"defaults.{setter.overrides[key][0]}") if setter else None
            rows.groups.append((key, self.base_choices.get(key, MISSING), option, source, note))
        for f in files:
            for path in leaves(f.data):
                if path not in rows.keys:
                    rows.keys[path] = (f.name, ("profile", f.name, path))
        base_leaves, tree_leaves = leaves(self.base), leaves(tree)
        by_group: dict[str, list[str]] = {}
        for path in dict.fromkeys([*tree_leaves, *base_leaves]):
            if get(tree, path) == get(self.base, path) or any(
                f"{path}.".startswith(f"{k}.") or k.startswith(f"{path}.") for k in rows.keys
            ):
                continue
            key = next(
                (k for k, (_, ks) in changed.items() if any(_under(path, p) for p in ks)), ""
            )
            by_group.setdefault(key, []).append(path)
        for key, paths in by_group.items():
            if key and len(paths) > MAX_GROUP_ROWS:
                rows.summed[key] = (changed[key][0] or _common_prefix(paths), len(paths))
                continue
            option = choices.get(key, "")
            group = key.partition("@")[0]
            for path in paths:
                inside = (
                    path.removeprefix(f"{changed[key][0]}.") if key and changed[key][0] else path
                )
                note = ("group", f"{group}/{option}", inside) if key else None
                rows.keys[path] = (f"{key}={option}" if key else "", note)
        return rows

    def _global_keys(self, group: str, option: str) -> list[str]:
        """What a ``_global_`` option sets: its own keys, and the packages of the options its
        defaults list places (``default@crossval``)."""
        data = yaml.safe_load((self.config_dir / group / f"{option}.yaml").read_text()) or {}
        out = []
        for entry in data.pop("defaults", None) or []:
            name = entry if isinstance(entry, str) else None
            if name and name != "_self_":
                name, _, at = name.partition("@")
                if (group, name) in self.files:
                    out.append(self.package(group, at or None, name))
        return [p for p in out if p] + list(leaves(data))


def _under(path: str, key: str) -> bool:
    """``path`` is ``key`` or inside it."""
    return f"{path}.".startswith(f"{key}.")


def _common_prefix(paths: list[str]) -> str:
    """The longest dotted prefix the paths share."""
    common = paths[0].split(".")
    for path in paths[1:]:
        parts = path.split(".")
        n = 0
        while n < min(len(common), len(parts)) and common[n] == parts[n]:
            n += 1
        common = common[:n]
    return ".".join(common)


@dataclass
class ProfileFile:
    """One profile file: its keys, its defaults list's entries (profiles and ``_self_``, in
    order) and group overrides (group key -> (the entry's key, option)), its comments."""

    name: str
    data: dict[str, Any]
    entries: list[str]
    overrides: dict[str, tuple[str, str]]
    comments: YamlComments


@dataclass
class ProfileRows:
    """A profile's rows: group choices ``(key, group default, option, set by, note source)``,
    keys (path -> (set by, note source)) and the groups whose many keys are summed up
    (key -> (package, count)). A note source is ``(kind, file, dotted key)``."""

    name: str
    builds_on: list[str]
    groups: list[tuple[str, Any, str, str, tuple[str, str, str] | None]] = field(
        default_factory=list
    )
    keys: dict[str, tuple[str, tuple[str, str, str] | None]] = field(default_factory=dict)
    summed: dict[str, tuple[str, int]] = field(default_factory=dict)


# The page.


def _profile_section(ref: Reference) -> list[str]:
    default_profile = ref.choices.get("profile", "quick")
    out = [
        "## Profiles",
        "",
        "A profile sets the scale (counts of grasps, seeds, epochs, trials, windows) and is "
        f"applied last, over every group. `{default_profile}` is the default; choose another with "
        "`--config profile=<name>`. A group choice or value given on the command line still wins "
        "over the profile's.",
        "",
        "Each profile's table is its composition (`--config profile=<name>`) against the groups' "
        "defaults (the configuration composed without a profile): every group choice and key "
        "that differs, and every key a profile file sets. *Set by* names the file that sets the "
        "value: the profile's own, a profile it builds on (its `defaults` list), or a group "
        "option a profile chooses (`energy=hpen`: the keys of `config/energy/hpen.yaml`).",
        "",
    ]
    default_rows = ref.profile_rows(default_profile)
    for name in [default_profile] + [o for o in ref.options["profile"] if o != default_profile]:
        info = ref.profile_file(name)
        rows = default_rows if name == default_profile else ref.profile_rows(name)
        tree, choices = ref.composed(name)
        default = " (the default)" if name == default_profile else ""
        out += [f"### {name}{default}", "", text(info.comments.header), ""]
        if rows.builds_on:
            merged = [
                "this file" if p == name else f"`config/profile/{p}.yaml`" for p in ref.chain(name)
            ]
            others = " and ".join(f"the {p} profile" for p in rows.builds_on[::-1])
            listed = ", ".join(f"`{e}`" for e in info.entries)
            out += [
                f"It builds on {others}: its `defaults` list ({listed}) composes "
                + ", then ".join(merged)
                + f", a later file's value winning, so the table holds {others}'s values too "
                f"(*Set by* `{rows.builds_on[0]}`).",
                "",
            ]
        notes = _Notes(ref)
        cells = []
        for key, base, option, source, note in rows.groups:
            about = notes(note)
            if key in rows.summed:
                package, count = rows.summed[key]
                summary = (
                    f"{count} keys under `{package}` change with it: see "
                    f"`config/{key.partition('@')[0]}/{option}.yaml`"
                )
                about = _join(about, summary) if about else summary
            shown = inline(base) if base is not MISSING else "not set"
            cells.append([f"group `{key}`", shown, f"`{option}`", _by(source), about])
        for path, (source, note) in rows.keys.items():
            cells.append(
                [
                    f"`{path}`",
                    inline(get(ref.base, path)),
                    inline(get(tree, path)),
                    _by(source),
                    notes(note),
                ]
            )
        out += table(["Key", "Group default", f"{name}", "Set by", "Note"], cells)
        if name == default_profile:
            continue
        back_groups = [g[0] for g in default_rows.groups if g[0] not in {h[0] for h in rows.groups}]
        back = [
            p
            for p in default_rows.keys
            if p not in rows.keys
            and not any(p.startswith(f"{pkg}.") for pkg, _ in rows.summed.values())
        ]
        if back or back_groups:
            items = [f"the group choice `{g}` (`{choices.get(g, '?')}`)" for g in back_groups]
            items += [f"`{p}` ({inline(get(tree, p))})" for p in back]
            out += [
                f"Keys the {default_profile} profile sets and {name} leaves at their group "
                f"defaults, so they change too when switching from {default_profile}: "
                + ", ".join(items)
                + ".",
                "",
            ]
    return out


def _by(source: str) -> str:
    return f"`{source}`" if source else ""


class _Notes:
    """The comment beside a key in the file that sets it, once per comment per table (a
    comment above a block of keys is shown at its first key, then "(see above)")."""

    def __init__(self, ref: Reference):
        self.ref = ref
        self.noted: set[tuple[str, str]] = set()

    def __call__(self, source: tuple[str, str, str] | None) -> str:
        if source is None:
            return ""
        kind, file, path = source
        group, _, option = file.partition("/") if kind == "group" else ("profile", "", file)
        comments = self.ref.files[(group, option)].keys
        parts = path.split(".")
        for i in range(len(parts), 0, -1):
            key = ".".join(parts[:i])
            if key in comments and (file, key) not in self.noted:
                self.noted.add((file, key))
                return text(comments[key])
            if key in comments:
                return "(see above)"
        return ""


def _options(ref: Reference, places: list[dict[str, Any]]) -> list[str]:
    """Each group placed in a section, with its options (a group placed several times, as the
    model families are, is listed once)."""
    out: list[str] = []
    profile = ref.choices.get("profile", "quick")
    for group in dict.fromkeys(p["group"] for p in places):
        mine = [p for p in places if p["group"] == group]
        where = ", ".join(f"`{p['package']}`" for p in mine)
        about = next((f" ({text(p['about'])})" for p in mine if p["about"]), "")
        if len(mine) == 1 and mine[0]["key"] == group:
            how = f"`--config {group}=<option>`"
        else:
            how = f"`--config 'overrides=[{mine[0]['key']}=<option>]'`"
        out += [f"Group `{group}` at {where}{about}; choose with {how}:", ""]
        for option in ref.options[group]:
            marks = []
            for p in mine:
                if option != p["chosen"]:
                    continue
                mark = "default" + (f" at `{p['package']}`" if len(mine) > 1 else "")
                if p["listed"] != p["chosen"]:
                    mark += f", chosen by the {profile} profile over `{p['listed']}`"
                marks.append(mark)
            mark = f" ({'; '.join(marks)})" if marks else ""
            header = ref.files[(group, option)].header
            desc = f": {text(header)}" if header else ""
            out.append(f"- `{option}`{mark}, `config/{group}/{option}.yaml`{desc}")
        out.append("")
    return out


def render(config_dir: str | Path, schema_path: str | Path) -> str:
    """The whole page."""
    ref = Reference(config_dir, schema_path)
    places = ref.placements()
    out = [
        "# Configuration reference",
        "",
        f"<!-- Generated by `{COMMAND}`: edit the comments in config/ or the schema, not this "
        "page. -->",
        "",
        "Every key of the configuration: its type and allowed values (from "
        "`workflow/schemas/config.schema.yaml`, which rejects unknown keys), its default (the "
        "composed default configuration, the quick profile) and what it is (from the comment "
        "beside it in `config/`). Section numbers (3.2, eq. 16, table 4.2) are the reference's.",
        "",
        "Set values on the command line of `snakemake` (and of `python -m graspstab.config show`, "
        "which prints the configuration they give):",
        "",
        "- a group option: `--config profile=study`, `--config contact=strict`;",
        "- values, merged into the composed tree: `--config 'train={seeds: [1, 2]}'`, "
        "`--config seed=7`;",
        "- raw Hydra overrides with dotted keys: `--config 'overrides=[labels.window_s=0.3]'`.",
        "",
        "A value marked *the quick profile* is set by `config/profile/quick.yaml`; the group "
        "default beside it is what the group's file says and what another profile may return "
        "to. A key under `<id>` or `<name>` is a field of every entry of a mapping whose keys you "
        "choose.",
        "",
        "## Groups",
        "",
    ]
    rows = []
    for place in places:
        options = ", ".join(
            f"**`{o}`**" if o == place["chosen"] else f"`{o}`" for o in ref.options[place["group"]]
        )
        rows.append(
            [
                f"`{place['key']}`",
                f"`{place['package'] or '(top level)'}`",
                options,
                text(place["about"]),
            ]
        )
    out += table(["Group", "At", "Options (default in bold)", "What it holds"], rows)
    out += _profile_section(ref)
    sections = [k for k, v in ref.default.items() if isinstance(v, dict)]
    for section in sections:
        own = [p for p in places if p["package"].split(".")[0] == section]
        out += [f"## {section}", ""]
        out += _options(ref, own)
        if not own:
            about = ref.root_comments.keys.get(section, "")
            out += [text(about), ""] if about else []
        out += _rows_table(ref.rows(section))
    out += ["## Top-level values", ""]
    out += _rows_table(ref.rows(""))
    return "\n".join(out).rstrip() + "\n"


def _rows_table(rows: list[Row]) -> list[str]:
    cells = [[f"`{r.path}`", text(r.type), r.default, text(r.description)] for r in rows]
    return table(["Key", "Type", "Default", "Description"], cells)


def main(argv: list[str] | None = None) -> int:
    """Print the reference page; a configuration error is one line on stderr and exit status 2."""
    import argparse
    import sys

    from graspstab.config.show import add_location_args, error_line, locate

    parser = argparse.ArgumentParser(prog="python -m graspstab.config.docs", description=__doc__)
    add_location_args(parser)
    args = parser.parse_args(argv)
    try:
        sys.stdout.write(render(*locate(args.config_dir, args.schema)))
    except ConfigError as exc:
        print(error_line(exc), file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
