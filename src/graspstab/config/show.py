"""The resolved configuration a ``snakemake --config KEY=VALUE ...`` run would load, as YAML."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from graspstab.config import load_config
from graspstab.config.errors import ConfigError

SCHEMA_RELPATH = Path("workflow") / "schemas" / "config.schema.yaml"


def parse_snakemake_config(entries: list[str]) -> dict[str, Any]:
    """``KEY=VALUE`` arguments parsed by ``snakemake --config``'s own parser."""
    from snakemake.cli import parse_config

    try:
        return parse_config(entries)
    except ValueError as exc:
        raise ConfigError(f"{exc} (got {entries})") from None


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


def add_location_args(parser: Any) -> None:
    """The --config-dir and --schema options of every command that reads the config tree."""
    parser.add_argument("--config-dir", help="the Hydra config tree (default: ./config)")
    parser.add_argument(
        "--schema",
        help="the schema (default: workflow/schemas/config.schema.yaml beside the config tree)",
    )


def error_line(exc: Exception) -> str:
    """A configuration error as the one line a command prints on stderr."""
    message = " ".join(line.strip() for line in str(exc).splitlines() if line.strip())
    return f"graspstab configuration error: {message}"


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
