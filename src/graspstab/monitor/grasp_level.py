"""Grasp-level evaluation (issue 16, 3): monitors run over every validation and test replay.

A window metric scores sampled windows; this module runs each monitor the way a controller would,
over a whole replay, and scores each grasp episode once (``monitor.episodes``). A replay enters
exactly as it enters the labelling stage (3.3.1): not diverged, not rejected by the depth rule,
with a non-empty usable interval;
its usable interval is ``labels.interval.usable_interval``'s and its timestep labels eq. 23's.
The monitor is causal, so a replay is scored only up to its interval's end. Scoring is batched
(``monitor.stream.score_trace``), which gives what the frame-by-frame monitor gives (tests).
"""

from __future__ import annotations

import logging
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from graspstab.labels.anatomy import failure, still_window_before
from graspstab.labels.interval import usable_interval
from graspstab.labels.replays import replay_grasps
from graspstab.labels.sources import source_channels, unstable_steps
from graspstab.labels.windows import step_counts, timestep_labels
from graspstab.monitor.early_warning import ScoredGrasp
from graspstab.monitor.episodes import EpisodeResult, evaluate_episode, first_scored
from graspstab.monitor.scoring import WindowScorer
from graspstab.monitor.stream import MonitorTrace, score_trace

log = logging.getLogger("graspstab.monitor")

SPLITS = ("val", "test")  # the held-out objects' replays (3.5.1)


@dataclass(frozen=True)
class Episode:
    """One replay as a monitor sees it: raw forces to the interval's end, and its ground truth."""

    object: str
    grasp_id: int
    split: str
    forces: np.ndarray  # (end, 5, 2) float32 [N]: normal, shear per fingertip
    speed: np.ndarray  # (end,) ||v_t|| [m/s]
    u: np.ndarray  # (end,) eq. 23's labels
    start: int  # settle index (3.3.1)
    end: int  # contact end (exclusive)
    contact_lost: bool  # the interval ended by contact loss (end < the trace's length)
    # the failure anatomy's view (labels.anatomy): whether the grasp fails after settling, and
    # its onset when a still observation window precedes it (None otherwise, or without rules)
    fails: bool = False
    still_onset: int | None = None


def read_episodes(
    replays: Sequence[tuple[str | Path, str | Path]],
    splits: Mapping[str, str],
    labels: Mapping[str, Any],
    dt: float,
    keep: Sequence[str] = SPLITS,
    grasp: tuple[str, int] | None = None,
) -> Iterator[Episode]:
    """The usable episodes of the (table, traces) pairs whose object's split is in ``keep`` (or
    only the one ``grasp``, (object, grasp id))."""
    anatomy = "anatomy" in labels
    wanted = dict.fromkeys(("velocity", "min_distance", "normal", "shear",
                            *source_channels(dict(labels)), *(("position",) if anatomy else ())))
    w = step_counts(labels["window_s"], labels["offset_s"], labels["horizon_s"], dt)[0]
    for g in replay_grasps(replays, splits, tuple(wanted), keep, grasp):
        tr = g.traces
        speed = np.linalg.norm(tr["velocity"].astype(np.float64), axis=1)
        dist = tr["min_distance"].astype(np.float64)
        ui = usable_interval(speed, dist, dt, labels["settle"], labels["contact_loss_s"])
        end = ui.contact_end
        # rejected by the depth rule, or no usable interval at all (the 3 s fallback
        # settle index lies past a replay that ended before it): no window either
        if ui.rejected or end <= ui.settle_index:
            continue
        forces = np.stack([tr["normal"][:end], tr["shear"][:end]], axis=-1)
        failed = failure(tr, dict(labels), dt, ui.settle_index, end) if anatomy else None
        still = failed is not None and still_window_before(
            timestep_labels(speed, labels["v_slip"]), ui.settle_index, failed[0], w)
        yield Episode(
            object=g.object, grasp_id=g.grasp_id, split=g.split,
            forces=forces.astype(np.float32), speed=speed[:end],
            u=unstable_steps(tr, dict(labels), ui.settle_index)[:end], start=ui.settle_index,
            end=end, contact_lost=end < len(dist), fails=failed is not None,
            still_onset=failed[0] if still else None,
        )  # fmt: skip


def score_episode(
    episode: Episode,
    trace: MonitorTrace,
    labels: Mapping[str, Any],
    dt: float,
) -> EpisodeResult:
    """One monitor's trace on one episode, scored (``monitor.episodes.evaluate_episode``)."""
    ready = first_scored(trace.prob)
    return evaluate_episode(
        trace.warning, episode.u, episode.start, episode.end, contact_lost=episode.contact_lost,
        dt=dt, offset_s=labels["offset_s"], horizon_s=labels["horizon_s"],
        object_id=episode.object, grasp_id=episode.grasp_id, split=episode.split,
        ready=len(trace.prob) if ready is None else ready,
    )  # fmt: skip


def scored_grasp(
    episode: Episode, trace: MonitorTrace, labels: Mapping[str, Any], dt: float
) -> ScoredGrasp:
    """What the early-warning evaluation keeps of one monitor's trace on one episode: its scores
    and, for a grasp that holds, its stable stretch [start, end - O - H) (as
    ``monitor.episodes`` bounds false warnings)."""
    frames = np.flatnonzero(np.isfinite(trace.prob))
    _, o, h = step_counts(0.0, labels["offset_s"], labels["horizon_s"], dt)
    stable_end = None if episode.fails else max(episode.start, episode.end - o - h)
    return ScoredGrasp(split=episode.split, frames=frames, scores=trace.prob[frames],
                       start=episode.start, end=episode.end, stable_end=stable_end,
                       onset=episode.still_onset, failing=episode.fails,
                       object=episode.object, grasp_id=episode.grasp_id)  # fmt: skip


def evaluate_monitors(
    episodes: Iterator[Episode] | Sequence[Episode],
    scorers: Mapping[str, WindowScorer],
    labels: Mapping[str, Any],
    dt: float,
    *,
    stride: int,
    debounce: int,
    batch_size: int = 4096,
    keep_traces: set[tuple[str, int]] | None = None,
    scored: dict[str, list[ScoredGrasp]] | None = None,
) -> tuple[pl.DataFrame, dict[tuple[str, int], dict[str, Any]]]:
    """Every scorer on every episode: one row per (monitor, grasp) with the episode's outcome, and
    for the grasps in ``keep_traces`` ((object, grasp id)) the episode and each monitor's trace;
    with ``scored``, each monitor's scores per grasp are appended to ``scored[monitor]`` (the
    early-warning evaluation's input, :func:`scored_grasp`)."""
    rows: list[dict[str, Any]] = []
    kept: dict[tuple[str, int], dict[str, Any]] = {}
    count = 0
    for episode in episodes:
        count += 1
        key = (episode.object, episode.grasp_id)
        for name, scorer in scorers.items():
            trace = score_trace(scorer, episode.forces, stride=stride, debounce=debounce,
                                batch_size=batch_size)  # fmt: skip
            result = score_episode(episode, trace, labels, dt)
            if scored is not None:
                scored.setdefault(name, []).append(scored_grasp(episode, trace, labels, dt))
            c = scorer.constants
            rows.append({"monitor": name, "threshold": c.threshold,
                         "window_steps": c.window_steps, **asdict(result)})  # fmt: skip
            if keep_traces is not None and key in keep_traces:
                kept.setdefault(key, {"episode": episode, "traces": {}})["traces"][name] = trace
        if count % 25 == 0:
            log.info("monitored %d replays", count)
    log.info("monitored %d replays with %d monitors", count, len(scorers))
    return pl.DataFrame(rows, schema=EPISODE_SCHEMA), kept


EPISODE_SCHEMA = {
    "monitor": pl.String, "threshold": pl.Float64, "window_steps": pl.Int64,
    "object": pl.String, "grasp_id": pl.Int64, "split": pl.String, "start": pl.Int64,
    "end": pl.Int64, "dt": pl.Float64, "onset": pl.Int64, "onset_kind": pl.String,
    "first_warning": pl.Int64, "warned_in_time": pl.Boolean, "lead_time_s": pl.Float64,
    "warnable": pl.Boolean, "false_warnings": pl.Int64, "stable_seconds": pl.Float64,
    "warning_seconds": pl.Float64,
}  # fmt: skip


def results_of(frame: pl.DataFrame) -> list[EpisodeResult]:
    """The episode table's rows back as :class:`EpisodeResult` (for ``summarise_episodes``)."""
    fields = EpisodeResult.__dataclass_fields__
    return [EpisodeResult(**{k: v for k, v in row.items() if k in fields})
            for row in frame.iter_rows(named=True)]  # fmt: skip


def timeline_grasp(
    frame: pl.DataFrame, monitor: str, split: str = "test"
) -> tuple[str, int] | None:
    """The grasp a timeline figure shows, by a fixed rule: of ``monitor``'s failing grasps of
    ``split`` warned in time, the one whose lead time is nearest their median (a typical warning,
    not the best); else its first failing grasp of the split; else its first grasp. Ties go to
    the lowest (object, grasp id). None when the split has no replay."""
    rows = frame.filter((pl.col("monitor") == monitor) & (pl.col("split") == split))
    rows = rows.sort(["object", "grasp_id"])
    if rows.is_empty():
        return None
    in_time = rows.filter(pl.col("warned_in_time"))
    if not in_time.is_empty():
        median = float(np.median(in_time["lead_time_s"].to_numpy()))
        pick = in_time.with_columns((pl.col("lead_time_s") - median).abs().alias("gap"))
        row = pick.sort(["gap", "object", "grasp_id"]).row(0, named=True)
    else:
        failing = rows.filter(pl.col("onset").is_not_null())
        row = (failing if not failing.is_empty() else rows).row(0, named=True)
    return row["object"], int(row["grasp_id"])
