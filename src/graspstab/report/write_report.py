"""Write ``results/report.html``: one self-contained page covering what the pipeline has built."""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

import graspstab
from graspstab.common.io import read_json, write_text
from graspstab.common.provenance import stable_hash
from graspstab.report import html as H
from graspstab.report.provenance import git_commit, package_versions, read_benchmark

log = logging.getLogger(__name__)
REPO_DIR = Path(graspstab.__file__).resolve().parents[2]


def _objects_section(config: dict[str, Any], metas: list[dict], bench: dict[str, dict]) -> str:
    rows = []
    for m in metas:
        oid = m["object_id"]
        entry = config["objects"]["items"][oid]
        rows.append(
            [
                oid,
                entry["split"],
                f"{m['mass']:.4f}",
                f"{m['volume'] * 1e6:.1f}",
                " x ".join(f"{e * 100:.1f}" for e in m["extents"]),
                m["watertight_before"],
                m["watertight_after"],
                m["convex_parts"],
                f"{bench[oid]['s']:.1f}" if oid in bench else "n/a",
            ]
        )
    return H.table(
        [
            "object",
            "split",
            "mass [kg]",
            "volume [cm3]",
            "extents [cm]",
            "watertight (raw)",
            "watertight (repaired)",
            "convex parts",
            "preprocess wall time [s]",
        ],
        rows,
        caption="Preprocessed objects (thesis 3.1.1, split of 4.1.1)",
    )


def _hand_section(hand: dict[str, Any]) -> str:
    rows = [
        [name, f"{lo:.4f}", f"{hi:.4f}"]
        for name, lo, hi in zip(
            hand["joint_names"], hand["joint_lower"], hand["joint_upper"], strict=True
        )
    ]
    tips = ", ".join(f"{f}: {b}" for f, b in hand["fingertips"].items())
    return (
        f"<p>{len(rows)} actuated finger joints plus a free wrist pose (joint "
        f"<code>{H.esc(hand['wrist_joint'])}</code>); fingertips: {H.esc(tips)}.</p>"
        + H.table(
            ["joint", "lower [rad]", "upper [rad]"],
            rows,
            caption="Finger joint limits, from the ORCA v2 description files",
        )
    )


def write_report(
    out_html: Path,
    config: dict[str, Any],
    figures: dict[str, Path],
    object_meta: list[Path],
    hand_json: Path,
    benchmark_files: list[Path],
) -> None:
    """Assemble the report from the artefacts the workflow produced."""
    metas = [read_json(p) for p in object_meta]
    bench = {Path(p).stem: read_benchmark(p) for p in benchmark_files}
    hand = read_json(hand_json)
    cfg_hash = stable_hash(config)
    profile = config["profile_name"]
    sections = [
        f'<p class="note">Profile <b>{H.esc(profile)}</b>, {len(metas)} objects. This report '
        "covers the stages built so far (objects and hand); later stages add grasps, replays, "
        "datasets and models. A quick-profile run is a smoke test of the pipeline, not a "
        "reproduction of the reference's numbers.</p>",
        "<h2>Objects</h2>",
        _objects_section(config, metas, bench),
        H.image(
            figures["objects"],
            "preprocessed objects",
            "Preprocessed objects with their CoACD convex parts (cf. thesis fig. 3.1).",
        ),
        "<h2>Hand and contact candidates</h2>",
        _hand_section(hand),
        H.image(
            figures["hand_candidates"],
            "hand with contact candidates",
            "ORCA hand with its 120 contact candidates (cf. thesis fig. 3.3).",
        ),
        H.image(
            figures["hand_capsules"],
            "capsule approximation",
            "Capsule and box approximation used by the penetration energies (cf. fig. 3.5a).",
        ),
        "<h2>Provenance</h2>",
        H.table(
            ["item", "value"],
            [
                ["config hash", cfg_hash],
                ["git commit", git_commit(REPO_DIR)],
                *[[f"package {k}", v] for k, v in package_versions().items()],
            ],
            caption="Run provenance",
        ),
        "<details><summary>Resolved configuration</summary><pre>"
        + H.esc(json.dumps(config, indent=2, sort_keys=True))
        + "</pre></details>",
    ]
    write_text(out_html, H.page(config["report"]["title"], sections))
    log.info("wrote %s (%d objects)", out_html, len(metas))
