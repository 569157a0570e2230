"""The report's "Failure anatomy" section: per protocol, how usable grasps fail after settling
(contact slip at a fingertip or an unseen link, rotation, servo saturation, compliance), when the
failing motion begins, and how many failing grasps leave an early warning anything to read: the
summaries and figures rule ``summarise_anatomy`` wrote, shown as written."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from graspstab.common.io import read_json
from graspstab.report import html as H

#: failure types, in the summaries' order, and how the table names them
TYPE_NAMES = {
    "fingertip_slip": "fingertip slip",
    "link_slip": "slip at an unseen link",
    "rotation": "rotation",
    "servo_saturation": "servo saturation",
    "compliance": "compliance",
}
#: the protocols the section can show, in order: (input prefix, name)
PROTOCOLS = (("reference", "main run"), ("creep_free", "creep-free benchmark"))


def missing_signal(summary: Mapping[str, Any]) -> str | None:
    """What the failure anatomy says the fingertip forces cannot see ahead of a failure: how the
    grasps that fail after settling begin (all splits). None when no grasp fails."""
    types = summary.get("types") or {}
    failed = int(summary.get("failed") or 0)
    if not failed:
        return None
    def part(key: str) -> str:  # noqa: E306
        n = int(types.get(key, 0))
        return f"{n} ({100 * n / failed:.0f} %) {TYPE_NAMES[key]}"
    unseen = int(types.get("link_slip", 0)) + int(types.get("compliance", 0)) \
        + int(types.get("rotation", 0))
    return (
        f"The failure anatomy ({summary.get('protocol', '?')} load) says what a fingertip-force "
        f"signal has to go on: of the {failed} grasps that fail after settling, "
        f"{part('fingertip_slip')}, {part('link_slip')}, {part('compliance')}, "
        f"{part('rotation')} and {part('servo_saturation')}. The fingertip sensors see the first "
        f"kind directly; {unseen} ({100 * unseen / failed:.0f} %) begin where no sensor is (slip "
        "at the palm or the phalanges, rotation, or the grasp yielding without sliding) and "
        "reach the fingertip forces only through the load they share. Sensing at those links, "
        "or loads that the fingertips carry, is what the anatomy suggests is missing from the "
        "signal."
    )


def _row(name: str, s: dict[str, Any]) -> list[Any]:
    q = s["onset_quartiles_s"]
    onset = "n/a" if q[1] is None else f"{q[1]:.2f} ({q[0]:.2f}-{q[2]:.2f})"
    return [name, s["protocol"], s["usable"], s["held"], s["failed"], s["moving_at_settle"],
            s["still_window"], onset, *(s["types"][t] for t in TYPE_NAMES)]  # fmt: skip


def anatomy_parts(anatomy: Mapping[str, Path] | None) -> list[str]:
    """The section, from the ``<protocol>_summary`` and ``<protocol>_figure`` inputs (none: the
    run did not get that far)."""
    anatomy = anatomy or {}
    present = [(p, n) for p, n in PROTOCOLS if f"{p}_summary" in anatomy]
    if not present:
        return []
    summaries = {p: read_json(anatomy[f"{p}_summary"]) for p, _ in present}
    rules = next(iter(summaries.values()))["rules"]
    parts = [
        H.heading(2, "anatomy", "Failure anatomy"),
        "<p>Every usable grasp that fails after settling (its object "
        f"{rules['fail_distance'] * 1000:g} mm from its settled pose, or contact ends), when the "
        "motion that ends in failure began (the last run of eq. 23 steps reaching it), and what "
        "gave way first, read from the physics rather than the sensed forces: a contact sliding "
        f"at {rules['slip_speed'] * 1000:g} mm/s or faster at a fingertip or at a link no sensor "
        f"sees; else the object spinning at {rules['spin']:g} rad/s or faster (rotation), a "
        f"closing joint's servo at {rules['saturation']:.0%} of its range (saturation), or "
        "neither (compliance). Only a failing grasp that leaves a still window (an observation "
        "window with no eq. 23 step between its settle index and its onset) gives an early "
        "warning anything to read; one already moving at settle can only be detected "
        '(docs/protocols.md, "Failure anatomy").</p>',
        H.table(
            ["run", "protocol", "usable grasps", "held", "failed", "moving at settle",
             "leave a still window", "onset after settle [s], median (IQR)",
             *TYPE_NAMES.values()],
            [_row(n, summaries[p]) for p, n in present],
            caption="Failure anatomy per protocol (all splits)",
        ),  # fmt: skip
    ]
    for p, n in present:
        key = f"{p}_figure"
        anchor = "anatomy-figure" if p == "reference" else f"anatomy-figure-{p.replace('_', '-')}"
        parts.append(
            H.image(anatomy[key], f"failure anatomy, {n}",
                    f"Onset of the failing motion after settling, by failure type ({n}).",
                    anchor, f"Failure anatomy ({n})")
            if key in anatomy
            else H.missing_figure(anchor, f"Failure anatomy ({n})", "Not produced.")
        )  # fmt: skip
    return parts
