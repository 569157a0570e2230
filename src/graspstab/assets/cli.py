"""Command line for the asset fetchers, so they can be run by hand outside Snakemake."""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
from collections.abc import Sequence

from graspstab.assets.download import DEFAULT_TIMEOUT
from graspstab.assets.errors import AssetError
from graspstab.assets.hand import HAND_COMMIT, HAND_URL_TEMPLATE, fetch_hand_description
from graspstab.assets.ycb import YCB_URL_TEMPLATE, fetch_ycb_object


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m graspstab.assets",
        description="Provide a YCB mesh or the ORCA hand description, checksum-verified.",
    )
    sub = parser.add_subparsers(dest="what", required=True)
    ycb = sub.add_parser("ycb", help="one YCB object: <dest>/textured.obj and source.json")
    ycb.add_argument("--object-id", required=True)
    ycb.add_argument("--dest", required=True, help="folder to write (e.g. resources/ycb/<id>)")
    ycb.add_argument(
        "--local-dir",
        default=os.environ.get("GRASPSTAB_YCB_DIR") or None,
        help="local YCB copy laid out <dir>/<id>/textured.obj (default: $GRASPSTAB_YCB_DIR)",
    )
    ycb.add_argument("--url-template", default=YCB_URL_TEMPLATE)
    ycb.add_argument("--sha256", default=None, help="expected sha256 of textured.obj")
    ycb.add_argument("--mesh-override", default=None, help="use this mesh file instead")
    hand = sub.add_parser("hand", help="the ORCA v2 description: <dest>/v2, LICENSE, source.json")
    hand.add_argument("--dest", required=True, help="folder to write")
    hand.add_argument(
        "--local-dir",
        default=os.environ.get("GRASPSTAB_HAND_DIR") or None,
        help="local orcahand_description copy (default: $GRASPSTAB_HAND_DIR)",
    )
    hand.add_argument("--url-template", default=HAND_URL_TEMPLATE)
    hand.add_argument("--commit", default=HAND_COMMIT)
    for p in (ycb, hand):
        p.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT, help="seconds")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run one fetch; print its source record, or one error line and return 1."""
    args = _parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    try:
        if args.what == "ycb":
            record = fetch_ycb_object(
                args.object_id,
                args.dest,
                local_dir=args.local_dir,
                url_template=args.url_template,
                sha256=args.sha256,
                mesh_override=args.mesh_override,
                timeout=args.timeout,
            )
        else:
            record = fetch_hand_description(
                args.dest,
                local_dir=args.local_dir,
                url_template=args.url_template,
                commit=args.commit,
                timeout=args.timeout,
            )
    except AssetError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    record.pop("files", None)
    print(json.dumps(record, indent=2, sort_keys=True))
    return 0
