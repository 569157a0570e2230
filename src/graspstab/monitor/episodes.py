"""Grasp-level scoring of a monitor's warnings against each grasp's failure onset (issue 16, 3).

The window metrics score sampled windows; a controller needs one timely warning per grasp. This
module scores one grasp episode, given per-frame warnings (the monitor's ``MonitorTrace.warning``,
or any thresholded score such as the proxy's ``score >= threshold``) and eq. 23's timestep labels
``u_t = 1[||v_t|| >= v_slip]`` over the usable interval ``[start, end)`` of 3.3.1 (``start`` the
settle index, ``end`` the contact end). All indices are trace rows; O and H are the labelling
stage's own step counts of the offset and horizon (``labels.windows.step_counts``: 200 and 300 at
0.1 s, 0.15 s and dt = 0.5 ms).

Definitions (the tests pin each):

* **Onset**: the first step ``n`` in ``[start, end)`` that begins a run of ``u == 1`` lasting at
  least H steps inside ``[start, end)`` (shorter blips are the slip noise the predictive label's
  horizon averages over). A run cut by ``end`` counts whatever its length only when the interval
  ended because contact was lost (``contact_lost``; ``usable_interval`` gives
  ``contact_end < len(trace)`` then) and ``u`` was still 1 at ``end - 1``: the object left the
  hand while moving, it fell. Its onset is that final run's first step. ``u`` outside
  ``[start, end)`` is never read. A grasp with an onset is *failing*, one without is *stable*.
* **Evaluated warnings**: ``warning`` is read on ``[lo, end)`` only, ``lo = max(start, ready)``,
  where ``ready`` is the first frame the monitor could warn on (its first scored frame; 0 for a
  score that exists on every frame). A warning already up at ``lo`` counts as raised at ``lo``.
  A *warning* is a rising edge of that signal.
* **First warning**: the first rising edge in ``[lo, end)``, before or after the onset.
* **Lead time**: ``(onset - first warning) * dt`` when the first warning precedes the onset,
  else undefined (None). As the issue states it, the *first* warning counts, even one that was
  dropped again before the onset: to the controller it was a warning of this grasp's failure. A
  monitor that warns early on everything is therefore caught by the false-warning rate and the
  warning share of stable grasps, not here.
* **Warned in time**: a failing grasp whose lead time is at least the offset, O steps (the
  reference's 0.1 s: the gap it leaves between a window and its predicted target). A failing
  grasp is *warnable* when such a warning was possible at all, ``onset - O >= lo``.
* **False warnings** (stable grasps only; None on failing ones, where every warning before the
  onset is a warning of that onset): the rising edges in the *stable stretch* ``[lo, end - O - H)``.
  The last O + H steps are left out because a warning at ``t`` predicts instability over
  ``[t + O, t + O + H)``, which there reaches past the interval and cannot be checked: the same
  rule that ends the labelling stage's window starts at ``contact_end - W - O - H`` (eq. 26).
* **Stable grasp-seconds**: the stable stretch's length times dt, the rate's denominator; the
  *warning share* is the fraction of it spent under a warning (a stuck warning is one edge).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from graspstab.common.runs import earliest_run
from graspstab.labels.windows import step_counts

__all__ = [
    "EpisodeResult",
    "evaluate_episode",
    "failure_onset",
    "first_scored",
    "lead_times",
    "rises",
    "summarise_episodes",
]


def _onset(
    u: np.ndarray, start: int, end: int, horizon_steps: int, contact_lost: bool
) -> tuple[int | None, str | None]:
    """Onset step and how it was found: ``horizon`` (a full run) or ``contact_lost``."""
    unstable = np.asarray(u[start:end]) == 1
    hit = earliest_run(unstable, horizon_steps, len(unstable))
    if hit is not None:
        return start + hit, "horizon"
    if contact_lost and len(unstable) and unstable[-1]:
        stable_at = np.flatnonzero(~unstable)
        return start + (int(stable_at[-1]) + 1 if len(stable_at) else 0), "contact_lost"
    return None, None


def failure_onset(
    u: ArrayLike, start: int, end: int, horizon_steps: int, contact_lost: bool = False
) -> int | None:
    """The onset (module docstring): the first step of ``[start, end)`` beginning a run of
    ``u == 1`` of at least ``horizon_steps`` inside it, or, if ``contact_lost``, of the run of
    ``u == 1`` that reaches ``end``; None for a stable grasp."""
    return _onset(np.asarray(u), start, end, horizon_steps, contact_lost)[0]


def rises(warning: ArrayLike, lo: int, hi: int) -> np.ndarray:
    """Steps in ``[lo, hi)`` where the warning rises (one already up at ``lo`` rises at ``lo``)."""
    w = np.asarray(warning, dtype=bool)[lo:hi]
    if not len(w):
        return np.zeros(0, dtype=np.int64)
    edge = w & ~np.concatenate([[False], w[:-1]])
    return lo + np.flatnonzero(edge)


def first_scored(prob: ArrayLike) -> int | None:
    """First frame with a probability (``MonitorTrace.prob`` is NaN until the buffer is full):
    the ``ready`` of :func:`evaluate_episode`."""
    scored = np.flatnonzero(np.isfinite(np.asarray(prob, dtype=np.float64)))
    return int(scored[0]) if len(scored) else None


@dataclass(frozen=True)
class EpisodeResult:
    """One grasp's outcome (definitions in the module docstring; steps are trace rows)."""

    object: str
    grasp_id: int
    split: str
    start: int  # usable interval [start, end)
    end: int
    dt: float
    onset: int | None  # None: a stable grasp
    onset_kind: str | None  # horizon | contact_lost | None
    first_warning: int | None  # first rising edge in [max(start, ready), end)
    warned_in_time: bool  # lead >= offset (failing grasps only; False on stable ones)
    lead_time_s: float | None  # onset - first warning, if the warning precedes the onset
    warnable: bool | None  # failing grasps: an in-time warning was possible; None if stable
    false_warnings: int | None  # stable grasps: rising edges in the stable stretch
    stable_seconds: float | None  # stable grasps: length of the stable stretch [s]
    warning_seconds: float | None  # stable grasps: time under warning in the stable stretch [s]

    @property
    def failing(self) -> bool:
        """Whether the grasp has an onset."""
        return self.onset is not None


def _check_int(name: str, value: Any) -> int:
    if isinstance(value, bool) or int(value) != value:
        raise ValueError(f"{name} must be an integer step; got {value!r}")
    return int(value)


def evaluate_episode(
    warning: ArrayLike,
    u: ArrayLike,
    start: int,
    end: int,
    *,
    contact_lost: bool,
    dt: float,
    offset_s: float,
    horizon_s: float,
    object_id: str,
    grasp_id: int,
    split: str,
    ready: int = 0,
) -> EpisodeResult:
    """Score one grasp: ``warning`` per frame (bool; a probability must be thresholded first,
    ``prob >= threshold``), ``u`` eq. 23's labels on the same frames, ``[start, end)`` the
    usable interval, ``contact_lost`` whether it ended by contact loss, ``ready`` the monitor's
    first scored frame (:func:`first_scored`)."""
    w = np.asarray(warning)
    if w.dtype != np.bool_:
        raise ValueError(
            f"warning must be a per-frame bool array (threshold a score first); got {w.dtype}"
        )
    labels = np.asarray(u)
    start, end = _check_int("start", start), _check_int("end", end)
    ready = _check_int("ready", ready)
    if w.ndim != 1 or labels.shape != w.shape:
        raise ValueError(f"warning {w.shape} and u {labels.shape} must be equal-length 1-d arrays")
    if not 0 <= start <= end <= len(w):
        raise ValueError(f"usable interval [{start}, {end}) must lie within the {len(w)} frames")
    if not np.isin(labels[start:end], (0, 1)).all():
        raise ValueError("u must hold eq. 23's labels, 0 or 1")
    _, o, h = step_counts(0.0, offset_s, horizon_s, dt)
    onset, kind = _onset(labels, start, end, h, bool(contact_lost))
    lo = max(start, ready)
    edges = rises(w, lo, end)
    first = int(edges[0]) if len(edges) else None
    common = {"object": object_id, "grasp_id": int(grasp_id), "split": split, "start": start,
              "end": end, "dt": float(dt), "onset": onset, "onset_kind": kind,
              "first_warning": first}  # fmt: skip
    if onset is None:
        hi = max(lo, end - o - h)
        return EpisodeResult(
            **common, warned_in_time=False, lead_time_s=None, warnable=None,
            false_warnings=len(rises(w, lo, hi)), stable_seconds=(hi - lo) * dt,
            warning_seconds=int(w[lo:hi].sum()) * dt,
        )  # fmt: skip
    lead = onset - first if first is not None and first < onset else None
    return EpisodeResult(
        **common, warned_in_time=lead is not None and lead >= o,
        lead_time_s=None if lead is None else lead * dt, warnable=onset - o >= lo,
        false_warnings=None, stable_seconds=None, warning_seconds=None,
    )  # fmt: skip


def lead_times(results: list[EpisodeResult]) -> np.ndarray:
    """Defined lead times [s] of the failing grasps (warned before their onset), for a histogram."""
    return np.array([r.lead_time_s for r in results if r.lead_time_s is not None], dtype=float)


def summarise_episodes(results: list[EpisodeResult]) -> dict[str, Any]:
    """One set's grasp-level figures (group by split, family or proxy before calling). Failing
    grasps split into ``warned_in_time``, ``warned_late`` (a first warning under the offset ahead
    of the onset, or after it) and ``not_warned``; ``in_time_share`` is over all failing grasps,
    ``in_time_share_warnable`` over those that left room for it. A figure without a denominator is
    None and ``undefined`` says why, never 0."""
    failing = [r for r in results if r.failing]
    stable = [r for r in results if not r.failing]
    in_time = sum(r.warned_in_time for r in failing)
    leads = lead_times(failing)
    stable_s = float(sum(r.stable_seconds or 0.0 for r in stable))
    false = int(sum(r.false_warnings or 0 for r in stable))
    warned_s = float(sum(r.warning_seconds or 0.0 for r in stable))
    undefined: dict[str, str] = {}
    if not failing:
        for key in ("in_time_share", "in_time_share_warnable", "median_lead_s"):
            undefined[key] = "no failing grasp"
    else:
        if not len(leads):
            undefined["median_lead_s"] = "no failing grasp was warned before its onset"
        if not any(r.warnable for r in failing):
            undefined["in_time_share_warnable"] = "no failing grasp left room for a warning in time"
    if stable_s <= 0:
        why = "no stable grasp" if not stable else "stable grasps have no stable stretch"
        undefined["false_warnings_per_stable_s"] = why
        undefined["stable_warning_share"] = why
    warnable = [r for r in failing if r.warnable]
    return {
        "grasps": len(results),
        "splits": sorted({r.split for r in results}),
        "failing_grasps": len(failing),
        "failing_by_contact_loss": sum(r.onset_kind == "contact_lost" for r in failing),
        "warnable_failing_grasps": len(warnable),
        "warned_in_time": in_time,
        "warned_late": sum(r.first_warning is not None and not r.warned_in_time for r in failing),
        "not_warned": sum(r.first_warning is None for r in failing),
        "in_time_share": in_time / len(failing) if failing else None,
        "in_time_share_warnable": (
            sum(r.warned_in_time for r in warnable) / len(warnable) if warnable else None
        ),
        "lead_time_grasps": int(len(leads)),
        "median_lead_s": float(np.median(leads)) if len(leads) else None,
        "stable_grasps": len(stable),
        "stable_seconds": stable_s,
        "false_warnings": false,
        "false_warnings_per_stable_s": false / stable_s if stable_s > 0 else None,
        "stable_warning_share": warned_s / stable_s if stable_s > 0 else None,
        "undefined": undefined,
    }
