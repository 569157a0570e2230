"""How far eq. 23's "unstable" (object speed at or above v_slip) is from the grasp failing: on a
finished run's replays, per protocol, the timestep labels of eq. 23 against a displacement label
(the object more than D from its settled position; the hand is fixed, so this is the object
leaving the grasp, not drifting), over each usable interval (3.3.1), and when each grasp fails.

    python benchmarks/label_sources.py <workdir> [--distances-mm 2 5 10] [--settle-mm-s 5 1.2]

Per protocol (results/replay, and results/creep_free/replay when the run has it) and distance D:
the usable steps; the share unstable by each label; their agreement and Cohen's kappa; the usable
grasps, and how many already move (eq. 23) at their settle index; those that fail (displacement
above D before contact ends), of those how many moved at settle and how many fail at least 0.5 s
after settling (the only grasps an early warning could help); and the median onset after
settling. A second table per protocol gives, for each settle speed (eq. 20's v_settle, 5 mm/s,
and others: 1.2 mm/s makes "settled" and eq. 23's "stable" the same), the usable grasps, the
baseline task's labelled windows (eq. 26 starts drawn as the labelling stage draws them, seed 42)
and their unstable ones, and how many are still now (no unstable step while observed) and of those
unstable: the windows on which an early warning can be measured at all. When the replays record
contact slip (graspstab.replay.slip), a third table gives, per slip speed (``--slip-mm-s``), eq.
23's labels against the ``contact_slip`` source's (graspstab.labels.sources). Uses the
repository's default labelling config (as label_preview.py).
"""

from __future__ import annotations

import argparse
import collections
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import polars as pl
import yaml

from graspstab.labels.interval import usable_interval
from graspstab.labels.label_windows import grasp_rng
from graspstab.labels.sources import unstable_steps
from graspstab.labels.windows import predictive_labels, step_counts, timestep_labels, window_starts
from graspstab.replay.traces import TraceFile

CONFIG = Path(__file__).resolve().parents[1] / "config"
STILL_BEFORE_S = 0.5  # a failure this long after settling leaves room for a warning


def displacement_labels(position: np.ndarray, settle: int, distance: float) -> np.ndarray:
    """1 where the object is more than ``distance`` [m] from its position at ``settle``."""
    p = np.asarray(position, dtype=np.float64)
    return (np.linalg.norm(p - p[settle], axis=1) > distance).astype(np.uint8)


def failure_onset(position: np.ndarray, settle: int, end: int, distance: float) -> int | None:
    """The first step in [settle, end) whose displacement exceeds ``distance``, or None."""
    hit = np.flatnonzero(displacement_labels(position, settle, distance)[settle:end])
    return settle + int(hit[0]) if hit.size else None


def confusion(a: np.ndarray, b: np.ndarray) -> dict[str, int]:
    """Counts of the four (a, b) label pairs."""
    a, b = np.asarray(a, bool), np.asarray(b, bool)
    return {"both": int((a & b).sum()), "first_only": int((a & ~b).sum()),
            "second_only": int((~a & b).sum()), "neither": int((~a & ~b).sum())}  # fmt: skip


def kappa(c: dict[str, int]) -> float:
    """Cohen's kappa of a :func:`confusion` (NaN when chance agreement is total)."""
    n = sum(c.values())
    if n == 0:
        return float("nan")
    agree = (c["both"] + c["neither"]) / n
    a1, b1 = (c["both"] + c["first_only"]) / n, (c["both"] + c["second_only"]) / n
    chance = a1 * b1 + (1 - a1) * (1 - b1)
    return float("nan") if chance == 1 else (agree - chance) / (1 - chance)


def _replays(replay_dir: Path, lab: dict, dt: float, settle: dict,
             extra: tuple[str, ...] = ()) -> Iterator[tuple]:  # fmt: skip
    """(row, traces, eq. 23 labels, usable interval) of every replay under ``replay_dir`` that
    neither diverged nor was rejected by the depth rule, with the settle rule ``settle`` (and
    the ``extra`` channels)."""
    for table_path in sorted(replay_dir.glob("*/replays_*.parquet")):
        traces = table_path.with_name(table_path.name.replace("replays_", "traces_"))
        table = pl.read_parquet(table_path).filter(~pl.col("diverged"))
        with TraceFile(traces.with_suffix(".npz")) as npz:
            for row in table.iter_rows(named=True):
                tr = npz.grasp(row["grasp_id"], ("velocity", "min_distance", "position", *extra))
                speed = np.linalg.norm(tr["velocity"].astype(np.float64), axis=1)
                dist = tr["min_distance"].astype(np.float64)
                ui = usable_interval(speed, dist, dt, settle, lab["contact_loss_s"])
                if not ui.rejected:
                    yield row, tr, timestep_labels(speed, lab["v_slip"]), ui


def protocol_rows(replay_dir: Path, lab: dict, dt: float, distances: list[float]) -> list[dict]:
    """One row per distance for the replays under ``replay_dir``."""
    tally = {d: collections.Counter() for d in distances}
    onsets: dict[float, list[float]] = {d: [] for d in distances}
    for _, tr, u, ui in _replays(replay_dir, lab, dt, lab["settle"]):
        s, e = ui.settle_index, ui.contact_end
        if e <= s:
            continue
        for d in distances:
            t = tally[d]
            t.update(confusion(u[s:e], displacement_labels(tr["position"], s, d)[s:e]))
            t["grasps"] += 1
            t["grasps moving at settle"] += int(u[s])
            onset = failure_onset(tr["position"], s, e, d)
            if onset is None:
                continue
            t["failing"] += 1
            t["moving_at_settle"] += int(u[s])
            t["late"] += int((onset - s) * dt >= STILL_BEFORE_S)
            onsets[d].append((onset - s) * dt)
    rows = []
    for d in distances:
        t = tally[d]
        c = {k: t[k] for k in ("both", "first_only", "second_only", "neither")}
        n = sum(c.values())
        rows.append({
            "D [mm]": 1000 * d, "steps": n,
            "eq23 unstable": (c["both"] + c["first_only"]) / n if n else float("nan"),
            "displaced": (c["both"] + c["second_only"]) / n if n else float("nan"),
            "agreement": (c["both"] + c["neither"]) / n if n else float("nan"),
            "kappa": kappa(c), "grasps": t["grasps"],
            "moving at settle": t["grasps moving at settle"], "failing": t["failing"],
            "failing, moving at settle": t["moving_at_settle"],
            f"failing >= {STILL_BEFORE_S} s after settle": t["late"],
            "median onset [s]": float(np.median(onsets[d])) if onsets[d] else float("nan"),
        })  # fmt: skip
    return rows


def records_slip(replay_dir: Path) -> bool:
    """Whether the replays under ``replay_dir`` record contact slip (replays before it did not)."""
    first = next(iter(sorted(replay_dir.glob("*/traces_*.npz"))), None)
    if first is None:
        return False
    with np.load(first) as npz:
        return any(name.endswith("_tip_slip") for name in npz.files)


def slip_rows(replay_dir: Path, lab: dict, dt: float, speeds: list[float]) -> list[dict]:
    """One row per slip speed: eq. 23's timestep labels against the contact_slip source's over
    every usable interval, and the share of eq. 23's unstable steps with no contact sliding."""
    tally = {v: collections.Counter() for v in speeds}
    for _, tr, u, ui in _replays(replay_dir, lab, dt, lab["settle"], ("tip_slip", "link_slip")):
        s, e = ui.settle_index, ui.contact_end
        if e <= s:
            continue
        for v in speeds:
            slip = unstable_steps(tr, {**lab, "source": "contact_slip", "slip_speed": v}, s)
            tally[v].update(confusion(u[s:e], slip[s:e]))
    rows = []
    for v in speeds:
        c = {k: tally[v][k] for k in ("both", "first_only", "second_only", "neither")}
        n = sum(c.values())
        moving = c["both"] + c["first_only"]
        rows.append({
            "slip [mm/s]": 1000 * v, "steps": n,
            "eq23 unstable": moving / n if n else float("nan"),
            "contact slip": (c["both"] + c["second_only"]) / n if n else float("nan"),
            "agreement": (c["both"] + c["neither"]) / n if n else float("nan"),
            "kappa": kappa(c),
            "eq23 unstable, no slip": c["first_only"] / moving if moving else float("nan"),
        })  # fmt: skip
    return rows


def still_windows(u: np.ndarray, starts: np.ndarray, w: int) -> np.ndarray:
    """Whether each window [s, s + W) has no unstable step (eq. 23): still now."""
    csum = np.concatenate([[0], np.cumsum(np.asarray(u, dtype=np.int64))])
    s = np.asarray(starts, dtype=np.int64)
    return (csum[s + w] - csum[s]) == 0


def window_rows(replay_dir: Path, lab: dict, dt: float, settle_speeds: list[float]) -> list[dict]:
    """One row per settle speed: usable grasps, labelled windows at the baseline task, unstable
    ones, still-now ones and still-now unstable ones."""
    w, o, h = step_counts(lab["window_s"], lab["offset_s"], lab["horizon_s"], dt)
    rows = []
    for v in settle_speeds:
        settle = {**lab["settle"], "speed_max": v}
        c: collections.Counter = collections.Counter()
        for row, _, u, ui in _replays(replay_dir, lab, dt, settle):
            rng = grasp_rng(42, row["object"], int(row["grasp_id"]))
            starts = window_starts(ui.settle_index, ui.contact_end, w, o, h,
                                   int(lab["windows_per_grasp"]), rng)  # fmt: skip
            if not len(starts):
                continue
            _, y = predictive_labels(u, starts, ui.contact_end, w, o, h,
                                     lab["label_low"], lab["label_high"])  # fmt: skip
            still = still_windows(u, starts, w) & (y >= 0)
            c.update(grasps=1, windows=int((y >= 0).sum()), unstable=int((y == 1).sum()),
                     still=int(still.sum()), still_unstable=int((still & (y == 1)).sum()))
        rows.append({"v_settle [mm/s]": 1000 * v, "usable grasps": c["grasps"],
                     "windows": c["windows"], "unstable": c["unstable"], "still now": c["still"],
                     "still now, unstable": c["still_unstable"]})  # fmt: skip
    return rows


def main(argv: list[str] | None = None) -> None:
    """Print one table per protocol."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdir", type=Path)
    ap.add_argument("--distances-mm", type=float, nargs="+", default=[2.0, 5.0, 10.0])
    ap.add_argument("--settle-mm-s", type=float, nargs="+", default=[5.0, 1.2],
                    help="settle speeds (eq. 20's v_settle) for the windows table")
    ap.add_argument("--slip-mm-s", type=float, nargs="+", default=[1.2, 5.0, 10.0],
                    help="contact slip speeds for the contact_slip table")
    args = ap.parse_args(argv)
    lab = yaml.safe_load((CONFIG / "labels" / "default.yaml").read_text())
    dt = yaml.safe_load((CONFIG / "replay" / "default.yaml").read_text())["timestep"]
    distances = [d / 1000 for d in args.distances_mm]
    protocols = {"reference": args.workdir / "results" / "replay",
                 "creep-free": args.workdir / "results" / "creep_free" / "replay"}  # fmt: skip
    pl.Config.set_tbl_rows(50)
    pl.Config.set_tbl_cols(20)
    pl.Config.set_tbl_width_chars(220)
    pl.Config.set_float_precision(4)
    for name, folder in protocols.items():
        if not folder.is_dir():
            continue
        print(f"\n{name} protocol ({folder}):")
        print(pl.DataFrame(protocol_rows(folder, lab, dt, distances)))
        settle = [v / 1000 for v in args.settle_mm_s]
        print(pl.DataFrame(window_rows(folder, lab, dt, settle)))
        if records_slip(folder):
            slips = [v / 1000 for v in args.slip_mm_s]
            print(pl.DataFrame(slip_rows(folder, lab, dt, slips)))


if __name__ == "__main__":
    main()
