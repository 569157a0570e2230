"""The resolved configuration a ``snakemake --config KEY=VALUE ...`` run would load, as YAML."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from graspstab.config import load_config
from graspstab.config.errors import ConfigError

SCHEMA_RELPATH = Path("workflow") / "schemas" / "config.schema.yaml"


def parse_snakemake_config(entries: list[str]) -> dict[str, Any]:
    """``KEY=VALUE`` arguments parsed exactly as ``snakemake --config`` parses them."""
    try:
        from snakemake.cli import parse_config
    except ImportError:  # snakemake moved its parser: the same rules, restated
        parse_config = _parse_config
    try:
        return parse_config(entries)
    except ValueError as exc:
        raise ConfigError(f"{exc} (got {entries})") from None


def _parse_config(entries: list[str]) -> dict[str, Any]:
    """Snakemake 9's ``parse_config``: int, float, True/False, YAML (BaseLoader), else string."""
    import re

    def as_bool(s: str) -> bool:
        if s in ("True", "False"):
            return s == "True"
        raise ValueError(s)

    def base_yaml(s: str) -> Any:
        return yaml.load(s, Loader=yaml.BaseLoader)  # BaseLoader: plain strings

    config: dict[str, Any] = {}
    for entry in entries:
        key, sep, val = entry.partition("=")
        if not sep:
            raise ValueError(
                "Invalid config definition: Config entries have to be defined as name=value pairs."
            )
        if not re.match(r"[a-zA-Z_][\w-]*\w$", key):
            raise ValueError(
                "Invalid config definition: Config entry must start with a valid identifier."
            )
        value: Any = None
        if val != "":
            for parser in (int, float, as_bool, base_yaml, str):
                try:
                    value = parser(val)
                except Exception:  # the next parser, as snakemake does
                    continue
                if not callable(value):
                    break
        _update(config, {key: value})
    return config


def _update(config: dict[str, Any], overwrite: dict[str, Any]) -> None:
    for key, value in overwrite.items():
        if isinstance(value, dict) and isinstance(config.get(key), dict):
            _update(config[key], value)
        else:
            config[key] = value


def locate(config_dir: str | Path | None, schema: str | Path | None) -> tuple[Path, Path]:
    """The config tree and schema: as given, else ``config/`` and the schema under the cwd."""
    cdir = Path(config_dir) if config_dir is not None else Path.cwd() / "config"
    if not (cdir / "config.yaml").is_file():
        where = "the given --config-dir" if config_dir is not None else "the current directory"
        raise ConfigError(
            f"no config tree at {cdir} ({where}): run this from the repository root or pass "
            "--config-dir"
        )
    spath = Path(schema) if schema is not None else cdir.resolve().parent / SCHEMA_RELPATH
    if not spath.is_file():
        raise ConfigError(
            f"no schema at {spath}: run this from the repository root or pass --schema"
        )
    return cdir, spath


def resolved(config_dir: Path, schema: Path, entries: list[str]) -> dict[str, Any]:
    """Compose, resolve and validate as the Snakefile does (asset files are not checked)."""
    cfg = parse_snakemake_config(entries)
    return load_config(config_dir, schema, snakemake_config=cfg, check_files=False)


def subtree(cfg: dict[str, Any], key: str) -> Any:
    """The value at dotted ``key``."""
    node: Any = cfg
    done: list[str] = []
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            where = ".".join(done) or "the top level"
            keys = ", ".join(map(str, node)) if isinstance(node, dict) else "none (a value)"
            raise ConfigError(f"no key {part!r} under {where} (--key {key}); its keys: {keys}")
        node = node[part]
        done.append(part)
    return node


def dump(value: Any) -> str:
    """YAML text of a mapping, list or scalar (mappings in block style, plain lists inline)."""
    text = yaml.safe_dump(
        value, sort_keys=False, default_flow_style=None, width=100, allow_unicode=True
    )
    return text.removesuffix("...\n")
