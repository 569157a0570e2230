"""What a policy did to one grasp, judged against the same grasp replayed without a reflex.

Definitions (one place, in code; docs/extensions.md "Closed loop" repeats them):

* **Drop**: the object leaves the hand: a run of at least ``labels.contact_loss_s`` (3.3.1's
  0.1 s contact-end rule) with no hand-object contact at all (d_t undefined) anywhere in the
  replay. Its step is the run's first.
* **Failure onset** (of the no-reflex run): the labelling stage's onset
  (``monitor.episodes.failure_onset`` on eq. 23's labels over 3.3.1's usable interval): the
  first step that begins a run of slip at least one horizon long, or the final run of slip of
  an object that fell. A grasp with an onset is *failing*, one without *holding*.
* **False alarm**: the reflex tightened on a grasp that holds without it.
* **Prevented**: the no-reflex run drops and this one does not; **worse**: this run drops and the
  no-reflex run does not (tightening can push an object out).
* **Lead time**: onset minus the first warning's frame (failing grasps warned before the onset).
* **Latency**: onset to the first tightened step (negative: the grip moved before the onset).
* **Slip distance**: the object's path length from the onset to its arrest (the first step of a
  horizon-long run below v_slip), its drop, or the end of the replay.
* **Grip cost**: the total fingertip normal force minus the no-reflex run's, step by step, from
  the first tightened step while both runs still hold the object (mean and peak), and the time
  spent with the targets moved in.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from graspstab.common.runs import earliest_run
from graspstab.labels.interval import steps_of, usable_interval
from graspstab.labels.sources import unstable_steps
from graspstab.labels.windows import step_counts
from graspstab.monitor.episodes import failure_onset
from graspstab.replay.run import REFLEX


def drop_step(min_distance: np.ndarray, loss_steps: int) -> int | None:
    """First step of the first run of ``loss_steps`` or more steps without contact (None: held)."""
    return earliest_run(np.isnan(np.asarray(min_distance)), loss_steps, len(min_distance))


@dataclass(frozen=True)
class Baseline:
    """The no-reflex run of one grasp: what every policy is judged against."""

    usable: bool  # a usable interval exists and the depth rule keeps it (else no verdict)
    start: int  # usable interval [start, end)
    end: int
    onset: int | None  # failure onset (None: holding)
    drop: int | None  # drop step (None: held)
    normal: np.ndarray  # (T,) total fingertip normal force [N]

    @property
    def failing(self) -> bool:
        """Whether the grasp has a failure onset without a reflex."""
        return self.onset is not None


def horizon_steps(labels: dict[str, Any], dt: float) -> int:
    """H of eq. 24 in steps (the onset's and the arrest's run length)."""
    return step_counts(labels["window_s"], labels["offset_s"], labels["horizon_s"], dt)[2]


def baseline_of(traces: dict[str, np.ndarray], labels: dict[str, Any], dt: float) -> Baseline:
    """Usable interval, onset and drop of a no-reflex run's traces."""
    speed = np.linalg.norm(traces["velocity"].astype(np.float64), axis=1)
    dist = traces["min_distance"].astype(np.float64)
    ui = usable_interval(speed, dist, dt, labels["settle"], labels["contact_loss_s"])
    usable = ui.rejected is None and ui.contact_end > ui.settle_index
    onset = None
    if usable:
        u = unstable_steps(traces, labels, ui.settle_index)[: ui.contact_end]
        onset = failure_onset(u, ui.settle_index, ui.contact_end, horizon_steps(labels, dt),
                              contact_lost=ui.contact_end < len(dist))  # fmt: skip
    return Baseline(usable, ui.settle_index, ui.contact_end, onset,
                    drop_step(dist, steps_of(labels["contact_loss_s"], dt)),
                    traces["normal"].astype(np.float64).sum(axis=1))  # fmt: skip


def slip_distance(speed: np.ndarray, onset: int, stop: int, v_slip: float, arrest_steps: int,
                  dt: float) -> tuple[float, int | None]:  # fmt: skip
    """Path length [m] from ``onset`` to the arrest (first step of an ``arrest_steps`` run below
    ``v_slip``) or ``stop``, and the arrest step (None: never arrested)."""
    seg = np.asarray(speed[onset:stop], dtype=np.float64)
    calm = earliest_run(seg < v_slip, arrest_steps, len(seg))
    end = len(seg) if calm is None else calm
    return float(seg[:end].sum() * dt), None if calm is None else onset + calm


def outcome(
    traces: dict[str, np.ndarray], reflex: Any, base: Baseline, labels: dict[str, Any], dt: float
) -> dict[str, Any]:
    """One policy's row for one grasp (definitions in the module docstring; times in s, forces
    in N, distances in mm). ``reflex``: the run's ``GripReflex`` (None for no reflex)."""
    dist = traces["min_distance"].astype(np.float64)
    speed = np.linalg.norm(traces["velocity"].astype(np.float64), axis=1)
    drop = drop_step(dist, steps_of(labels["contact_loss_s"], dt))
    warned = reflex.warn_frames[0] if reflex is not None and reflex.warn_frames else None
    offset = traces.get(REFLEX, np.zeros(len(dist)))
    tight = np.flatnonzero(offset > 0)
    first_tight = int(tight[0]) if len(tight) else None
    row: dict[str, Any] = {
        "usable": base.usable,
        "failing": base.failing,
        "baseline_dropped": base.drop is not None,
        "dropped": drop is not None,
        "drop_s": np.nan if drop is None else drop * dt,
        "fired": first_tight is not None,
        "warn_s": np.nan if warned is None else warned * dt,
        "tighten_s": np.nan if first_tight is None else first_tight * dt,
        "tightened_s": len(tight) * dt,
        "peak_offset_rad": float(offset.max(initial=0.0)),
    }
    row["prevented"] = row["baseline_dropped"] and not row["dropped"]
    row["worse"] = row["dropped"] and not row["baseline_dropped"]
    row["false_alarm"] = row["fired"] and base.usable and not base.failing
    onset = base.onset
    row["onset_s"] = np.nan if onset is None else onset * dt
    early = onset is not None and warned is not None and warned <= onset
    row["lead_s"] = (onset - warned) * dt if early else np.nan
    timed = onset is not None and first_tight is not None
    row["latency_s"] = (first_tight - onset) * dt if timed else np.nan
    if onset is not None and onset < len(speed):
        stop = len(speed) if drop is None else drop
        slip, arrest = slip_distance(speed, onset, max(onset, stop), labels["v_slip"],
                                     horizon_steps(labels, dt), dt)  # fmt: skip
        row["slip_mm"], row["arrest_s"] = slip * 1e3, np.nan if arrest is None else arrest * dt
    else:
        row["slip_mm"], row["arrest_s"] = np.nan, np.nan
    added_mean = added_peak = np.nan
    if first_tight is not None:
        # both runs hold the object (neither has dropped) over [first_tight, both_end)
        ends = [s for s in (drop, base.drop) if s is not None]
        both_end = min(len(dist), len(base.normal), *ends)
        if both_end > first_tight:
            mine = traces["normal"].astype(np.float64).sum(axis=1)[first_tight:both_end]
            added = mine - base.normal[first_tight:both_end]
            added_mean, added_peak = float(added.mean()), float(added.max())
    row["added_normal_mean_n"], row["added_normal_peak_n"] = added_mean, added_peak
    return row
