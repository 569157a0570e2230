"""The report's "Objects" and "Hand and contact candidates" sections: what preprocessing and the
hand build wrote, shown as written (3.1.1, 3.1.2), with their figures."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from graspstab.report import html as H


def objects_table(
    config: Mapping[str, Any], metas: Sequence[Mapping[str, Any]], bench: Mapping[str, dict]
) -> str:
    """One row per preprocessed object (its meta.json) with its split and the preprocessing
    job's wall time (``bench``: object -> its benchmark record)."""
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


def objects_parts(
    config: Mapping[str, Any],
    metas: Sequence[Mapping[str, Any]],
    bench: Mapping[str, dict],
    figure: Path,
) -> list[str]:
    """The section "Objects": the table and the objects' figure (fig. 3.1)."""
    return [
        H.heading(2, "objects", "Objects"),
        objects_table(config, metas, bench),
        H.image(
            figure,
            "preprocessed objects",
            "Preprocessed objects with their CoACD convex parts (cf. thesis fig. 3.1).",
            "objects-figure",
        ),
    ]


def hand_table(hand: Mapping[str, Any]) -> str:
    """The hand's joints and limits (hand.json), with its wrist joint and fingertips."""
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


def hand_parts(hand: Mapping[str, Any], candidates: Path, capsules: Path) -> list[str]:
    """The section "Hand and contact candidates": the joint table, the contact candidates
    (fig. 3.3) and the capsule approximation (fig. 3.5a)."""
    return [
        H.heading(2, "hand", "Hand and contact candidates"),
        hand_table(hand),
        H.image(
            candidates,
            "hand with contact candidates",
            "ORCA hand with its 120 contact candidates (cf. thesis fig. 3.3).",
            "hand-candidates",
            "Contact candidates (fig. 3.3)",
        ),
        H.image(
            capsules,
            "capsule approximation",
            "Capsule and box approximation used by the penetration energies (cf. fig. 3.5a).",
            "hand-capsules",
            "Capsule approximation (fig. 3.5a)",
        ),
    ]
