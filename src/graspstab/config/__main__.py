"""``python -m graspstab.config show``: the resolved configuration, composed and validated as the
Snakefile does. (The reference page, docs/configuration.md, is a docs tool: ``python -m
graspstab.config.docs``.)"""

from __future__ import annotations

import argparse
import sys

from graspstab.config import show as show_mod
from graspstab.config.errors import ConfigError


def main(argv: list[str] | None = None) -> int:
    """Run one subcommand; a configuration error is one line on stderr and exit status 2."""
    parser = argparse.ArgumentParser(prog="python -m graspstab.config", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    show = sub.add_parser(
        "show",
        help="print the resolved configuration as YAML",
        description="Print the configuration `snakemake --config KEY=VALUE ...` would run, "
        "composed and validated as the Snakefile does (asset files are not checked).",
    )
    show.add_argument("entries", nargs="*", metavar="KEY=VALUE", help="as for snakemake --config")
    show.add_argument("--key", help="print only this subtree (dotted path, e.g. train.threshold)")
    show_mod.add_location_args(show)
    args = parser.parse_args(argv)
    try:
        config_dir, schema = show_mod.locate(args.config_dir, args.schema)
        cfg = show_mod.resolved(config_dir, schema, args.entries)
        sys.stdout.write(show_mod.dump(show_mod.subtree(cfg, args.key) if args.key else cfg))
    except ConfigError as exc:
        print(show_mod.error_line(exc), file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
