"""Failure anatomy: when and how each usable grasp fails after settling, read from the physics
(contact slip, servo forces, object spin), never from the forces the models see.

Per replay with a usable interval (3.3.1):

* **failed** once the object is ``fail_distance`` from its pose at the settle index (hand frame)
  or contact ends (3.3.1's contact end) before the replay does; else **held**;
* **onset**: the start of the last run of eq. 23's unstable steps that reaches the failure
  (gaps up to ``gap_s`` bridged), the moment the motion that ends in failure began; a grasp
  whose run starts at the settle index was already moving when it settled;
* **type**, judged from the onset to the failure: ``fingertip_slip`` or ``link_slip`` when a
  fingertip's or another link's contact slides at ``slip_speed`` or faster (the earlier of the
  two; a fingertip on a tie), else, with no contact sliding, ``rotation`` (the object spins at
  ``spin`` rad/s or faster), ``servo_saturation`` (a closing joint's servo at ``saturation`` of
  its range: the finger yields) or ``compliance`` (the object moves with the soft contacts and
  servos, nothing sliding or saturated);
* **still window**: whether an observation window (W of the baseline task) fits between the
  settle index and the onset with no unstable step, i.e. whether an early warning had anything
  to read before the failure began.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from graspstab.labels.interval import steps_of, usable_interval
from graspstab.labels.sources import displacement
from graspstab.labels.windows import step_counts, timestep_labels

TYPES = ("fingertip_slip", "link_slip", "rotation", "servo_saturation", "compliance")
#: the trace channels the anatomy reads
CHANNELS = ("position", "velocity", "min_distance", "tip_slip", "link_slip", "servo_load", "spin")


def first(mask: np.ndarray) -> int | None:
    """Index of the first True, or None."""
    hit = np.flatnonzero(mask)
    return int(hit[0]) if len(hit) else None


def motion_onset(u: np.ndarray, settle: int, fail: int, gap: int) -> int:
    """Start of the last run of ``u`` (gaps of at most ``gap`` zeros bridged) that reaches step
    ``fail - 1``, never before ``settle``; ``fail`` when ``u`` is 0 there and just before."""
    t, zeros = fail - 1, 0
    onset = fail
    while t >= settle:
        if u[t]:
            onset, zeros = t, 0
        else:
            zeros += 1
            if zeros > gap:
                break
        t -= 1
    return onset


def still_window_before(u: np.ndarray, settle: int, onset: int, w: int) -> bool:
    """Whether some W-step window in [settle, onset) has no unstable step."""
    if onset - settle < w:
        return False
    seg = np.asarray(u[settle:onset], dtype=np.int64)
    csum = np.concatenate([[0], np.cumsum(seg)])
    return bool((csum[w:] - csum[:-w] == 0).any())


def failure(
    traces: dict[str, np.ndarray], labels: dict[str, Any], dt: float, settle: int, end: int
) -> tuple[int, int] | None:
    """(onset, failure step) of a replay whose usable interval is [settle, end), or None when
    it holds: the failure is its object's first step ``fail_distance`` from the settled pose, or
    ``end`` when contact ends before the replay does; the onset starts the motion that ends in it
    (:func:`motion_onset` on eq. 23's labels)."""
    rule = labels["anatomy"]
    moved = displacement(traces["position"], settle)
    crossed = first(moved[settle:end] >= float(rule["fail_distance"]))
    if crossed is None and end >= len(moved):
        return None
    fail = settle + crossed if crossed is not None else end
    speed = np.linalg.norm(np.asarray(traces["velocity"], dtype=np.float64), axis=1)
    u = timestep_labels(speed, labels["v_slip"])
    return motion_onset(u, settle, fail, steps_of(rule["gap_s"], dt)), fail


def grasp_anatomy(
    traces: dict[str, np.ndarray], labels: dict[str, Any], dt: float
) -> dict[str, Any] | None:
    """The anatomy of one replay (None: no usable interval, as 3.3.1 rejects or ends it)."""
    rule = labels["anatomy"]
    speed = np.linalg.norm(np.asarray(traces["velocity"], dtype=np.float64), axis=1)
    dist = np.asarray(traces["min_distance"], dtype=np.float64)
    ui = usable_interval(speed, dist, dt, labels["settle"], labels["contact_loss_s"])
    settle, end = ui.settle_index, ui.contact_end
    if ui.rejected or end <= settle:
        return None
    lost = end < len(dist)
    out: dict[str, Any] = {"settle_s": settle * dt, "outcome": "held", "type": None,
                           "onset_s": np.nan, "fail_s": np.nan, "tip_slip_s": np.nan,
                           "link_slip_s": np.nan, "saturation_s": np.nan, "peak_spin": np.nan,
                           "moving_at_settle": False, "still_window": False,
                           "contact_lost": bool(lost)}  # fmt: skip
    failed = failure(traces, labels, dt, settle, end)
    if failed is None:
        return out
    onset, fail = failed
    u = timestep_labels(speed, labels["v_slip"])
    seg = slice(onset, max(fail, onset + 1))
    tip = np.asarray(traces["tip_slip"], dtype=np.float64)[seg].max(axis=1, initial=0.0)
    link = np.asarray(traces["link_slip"], dtype=np.float64)[seg]
    sat = np.asarray(traces["servo_load"], dtype=np.float64)[seg]
    spin = np.asarray(traces["spin"], dtype=np.float64)[seg]
    slide = float(rule["slip_speed"])
    t_tip, t_link = first(tip >= slide), first(link >= slide)
    t_sat = first(sat >= float(rule["saturation"]))
    if t_tip is not None and (t_link is None or t_tip <= t_link):
        kind = "fingertip_slip"
    elif t_link is not None:
        kind = "link_slip"
    elif spin.max(initial=0.0) >= float(rule["spin"]):
        kind = "rotation"
    elif t_sat is not None:
        kind = "servo_saturation"
    else:
        kind = "compliance"
    w = step_counts(labels["window_s"], labels["offset_s"], labels["horizon_s"], dt)[0]
    out.update({
        "outcome": "failed", "type": kind, "onset_s": (onset - settle) * dt,
        "fail_s": (fail - settle) * dt,
        **{k: np.nan if t is None else t * dt for k, t in
           (("tip_slip_s", t_tip), ("link_slip_s", t_link), ("saturation_s", t_sat))},
        "peak_spin": float(spin.max(initial=0.0)), "moving_at_settle": onset == settle,
        "still_window": still_window_before(u, settle, onset, w),
    })  # fmt: skip
    return out


def summarise(rows: Iterable[dict[str, Any]]) -> dict[str, Any]:
    """Counts per outcome and type, onset quartiles [s after settle], and how many failing grasps
    leave a still window before their onset."""
    rows = list(rows)
    failed = [r for r in rows if r["outcome"] == "failed"]
    onsets = np.array([r["onset_s"] for r in failed], dtype=np.float64)
    q = np.quantile(onsets, [0.25, 0.5, 0.75]).tolist() if len(onsets) else [None] * 3
    return {
        "usable": len(rows),
        "held": len(rows) - len(failed),
        "failed": len(failed),
        "types": {t: sum(r["type"] == t for r in failed) for t in TYPES},
        "moving_at_settle": sum(bool(r["moving_at_settle"]) for r in failed),
        "still_window": sum(bool(r["still_window"]) for r in failed),
        "onset_quartiles_s": q,
    }
