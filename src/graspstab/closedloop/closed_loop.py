"""Closed-loop replays of one object's grasps: every policy on the same grasps, seeds and load.

Each grasp is replayed first without a reflex (the baseline every policy is judged against,
``closedloop.outcome``), then once per policy with its reflex in the loop. The physics is the
replay stage's (``replay.run.run_replay``, the protocol's load, the same stop rules); only the
reflex reads the sensors. Under the load ramp the closed loop's load path is its own option
(``closed_loop.ramp_path``): ``hold`` keeps the load the object first slid at, so a grip that
raises the friction capacity above it arrests the slip.
"""

from __future__ import annotations

import json
import logging
import time
import zlib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import polars as pl

from graspstab.closedloop.outcome import Baseline, baseline_of, outcome
from graspstab.closedloop.policies import Policy, actuator_axes, make_reflex
from graspstab.closedloop.reflex import GripReflex, ReflexParams
from graspstab.closedloop.sweep import Variant, default_variant
from graspstab.common.io import read_parquet, save_npz, write_parquet
from graspstab.labels.interval import steps_of
from graspstab.replay.grasp_setup import deep_stop, grasp_load, slip_sampler
from graspstab.replay.protocols import creep_free_replay, replay_params
from graspstab.replay.run import Fork, ReplayResult, run_replay
from graspstab.replay.scene import build_replay_scene, place_grasp
from graspstab.replay.slip import SlipSampler

log = logging.getLogger("graspstab.closedloop")


def protocol_params(config: dict[str, Any], protocol: str) -> dict[str, Any]:
    """The replay params of ``protocol`` (``reference``: the run's replay group; ``creep_free``:
    it under the load ramp with creep_free's contact model, squeeze and length, as the
    creep-free benchmark replays), with the closed loop's ramp path."""
    if protocol == "reference":
        return replay_params(config["replay"])
    if protocol != "creep_free":
        raise ValueError(f"closed_loop.protocols: unknown protocol {protocol!r}; valid: "
                         "reference, creep_free")  # fmt: skip
    return with_ramp_path(creep_free_replay(config), config["closed_loop"]["ramp_path"])


def with_ramp_path(params: dict[str, Any], path: str | None) -> dict[str, Any]:
    """The replay params with the load ramp's path replaced (unchanged unless the protocol is the
    ramp: gravity has no load, and the perturbation's load is open-loop by design)."""
    if path is None or params["protocol"] != "ramp":
        return params
    return {**params, "ramp": {**params["ramp"], "path": path}}


def acts_on(grip: GripReflex, traces: dict[str, np.ndarray]) -> bool:
    """Whether a monitor-driven reflex would move the targets within the no-reflex run.

    Until the reflex first tightens, the closed-loop replay is the no-reflex one step for step
    (same state, same targets), so the monitor sees exactly the no-reflex run's forces. Scanning
    them (``grip`` then holds the warnings the loop would raise) decides whether the loop can
    differ at all; only a reflex that tightens needs its replay."""
    grip.observe(0, traces["normal"], traces["shear"])
    return bool(grip.on_steps) and grip.on_steps[0] < len(traces["normal"])


def same_run_key(grip: GripReflex) -> tuple[int, float, float] | None:
    """What decides a reflex run once its first tightening is known: its step, amount and rate.

    With release ``never`` nothing after the first tightening depends on the monitor, and until
    then the run is the no-reflex one, so two reflexes with the same key give the same replay
    (a scheduled one knows its step; a monitor's comes from ``acts_on``'s scan). None where the
    release rule keeps the monitor in charge (``calm``)."""
    if grip.params.release != "never" or not grip.on_steps:
        return None
    return (grip.on_steps[0], grip.params.amount, grip.params.rate)


def timeline_rank(row: dict[str, Any]) -> int:
    """How well one grasp's row shows the reflex at work: 4 a drop it prevented, 3 a failing
    grasp it tightened on, 2 any failing grasp, 1 a grasp it tightened on, 0 the rest."""
    if not row["usable"]:
        return -1
    if row["prevented"]:
        return 4
    if row["failing"]:
        return 3 if row["fired"] else 2
    return 1 if row["fired"] else 0


def replay_once(scene: Any, data: mujoco.MjData, grasp: dict[str, Any], object_id: str,
                params: dict[str, Any], controller: Any = None,
                slip: SlipSampler | None = None, forks: dict[int, Fork] | None = None,
                start: Fork | None = None,
                prefix: dict[str, np.ndarray] | None = None) -> ReplayResult:  # fmt: skip
    """One replay of ``grasp`` (a grasp-table row) from its placement, with ``controller``
    (``slip``: the scene's slip sampler, ``replay.grasp_setup.slip_sampler``; None: a new one,
    which copies the model); ``forks`` collects where it can be continued from, ``start`` and
    ``prefix`` continue an earlier replay of the grasp from one of its forks
    (``replay.run.run_replay``)."""
    pos = np.array([grasp[f"wrist_{a}"] for a in "xyz"])
    quat = np.array([grasp[f"quat_{a}"] for a in "wxyz"])
    joints = np.array([grasp[f"theta_{k:02d}"] for k in range(16)])
    place_grasp(scene, data, pos, quat, joints, np.asarray(params["gravity"], dtype=np.float64))
    load = grasp_load(params, scene, scene.model.opt.gravity.copy(), object_id,
                      int(grasp["grasp_id"]))  # fmt: skip
    dt = float(params["timestep"])
    return run_replay(
        scene.model, data, scene.layout, int(params["steps"]), int(params["chunk_steps"]),
        max(1, round(float(params["stop_after_loss_s"]) / dt)), load, scene.object_body,
        deep_stop(params), controller=controller, slip=slip, forks=forks, start=start,
        prefix=prefix,
    )  # fmt: skip


def arm_step_of(base: Baseline, arming: str, arm_s: float, window_steps: int, dt: float) -> int:
    """Where every monitor of one grasp is armed (and ``always`` fires): ``fixed``, ``arm_s``
    after placement; ``settle``, the no-reflex run's settle index plus the monitored window less
    one step (the first window counted starts at settling, as every training window does), and
    never before ``arm_s``. A grasp without a usable interval is armed at ``arm_s``."""
    fixed = steps_of(arm_s, dt)
    if arming == "fixed" or not base.usable:
        return fixed
    if arming != "settle":
        raise ValueError(f"closed_loop.arming must be settle or fixed, got {arming!r}")
    return max(fixed, base.start + max(1, window_steps) - 1)


def load_step_of(scene: Any, params: dict[str, Any], object_id: str, grasp_id: int) -> int | None:
    """The step the protocol's load starts on this grasp (None under gravity alone): drawn from
    the grasp's own stream, as the replay draws it (call after placing the grasp)."""
    load = grasp_load(params, scene, scene.model.opt.gravity.copy(), object_id, grasp_id)
    return None if load is None else round(float(load.start_s) / float(params["timestep"]))


def shuffled_steps(offsets: Sequence[int | None], arms: Sequence[int], seed: int,
                   key: str) -> list[int | None]:  # fmt: skip
    """A shuffled control's step per grasp: a permutation (seeded by ``seed`` and ``key``) deals
    each grasp an offset from arming out of ``offsets`` (None: that monitor never tightened
    there), added to this grasp's own arming step. ``offsets`` are this run's grasps' own (a
    permutation of them), or a pool from more grasps (every object of a cross-validation run):
    then each grasp gets a different one, drawn without replacement."""
    if len(offsets) < len(arms):
        raise ValueError(f"{len(offsets)} tightening offsets to deal to {len(arms)} grasps")
    rng = np.random.default_rng([int(seed), zlib.crc32(key.encode())])
    order = rng.permutation(len(offsets))[: len(arms)]
    return [None if offsets[j] is None else arms[i] + int(offsets[j])
            for i, j in enumerate(order)]  # fmt: skip


def tightening_offsets(table: pl.DataFrame, dt: float) -> dict[str, list[int | None]]:
    """Each monitor's first tightening step counted from arming, per usable grasp of a closed-loop
    table (None where it never tightened): the pool a shuffled control deals from."""
    out: dict[str, list[int | None]] = {}
    rows = table.filter(pl.col("usable") & (pl.col("parameter") == "")
                        & pl.col("threshold").is_not_nan())  # fmt: skip
    for (policy,), part in rows.group_by(["policy"], maintain_order=True):
        out[str(policy)] = [None if not np.isfinite(t) else round((t - a) / dt)
                            for t, a in zip(part["tighten_s"], part["arm_s"], strict=True)]
    return out


def closed_loop_object(
    object_id: str,
    object_dir: str | Path,
    hand_dir: str | Path,
    grasp_table: str | Path | Sequence[str | Path],
    params: dict[str, Any],
    labels: dict[str, Any],
    policies: Sequence[Policy],
    reflex: ReflexParams,
    *,
    stride: int = 1,
    debounce: int = 1,
    arm_s: float = 0.0,
    arming: str = "fixed",
    window_steps: int = 1,
    fresh: bool = False,
    shuffle_seed: int = 0,
    oracle_lead_s: float | None = None,
    grasp_ids: Sequence[int] | None = None,
    max_grasps: int | None = None,
    variants: Sequence[Variant] = (),
    keep_traces: bool = False,
    timeline: str | None = None,
    offset_pool: Mapping[str, Sequence[int | None]] | None = None,
) -> tuple[pl.DataFrame, dict[tuple[int, str], dict[str, np.ndarray]]]:
    """Every grasp (or ``grasp_ids``; at most ``max_grasps``, the lowest ids) of ``grasp_table``
    (one shard table or several) under every policy (with ``reflex``, ``debounce``, armed by
    ``arming`` with ``arm_s`` and ``window_steps``, ``fresh``: :func:`arm_step_of`), then under
    every ``variants`` entry (``closedloop.sweep``). Shuffled controls run last, once every
    grasp's monitor runs have given their tightening times (:func:`shuffled_steps`, seeded by
    ``shuffle_seed`` and the object and monitor). Returns one row per grasp and policy or
    variant (``closedloop.outcome``'s columns, the variant's parameter and value, the arming
    step's time; no wall time: that differs on every run, so only the log has it) and, with
    ``keep_traces``, each run's traces keyed (grasp id, label); without it the traces are
    dropped once the grasp's rows are made. ``timeline`` (a label): the traces returned are
    instead the no-reflex and that label's runs of the one grasp that shows the reflex best
    (``timeline_rank``). ``offset_pool`` (monitor -> offsets, :func:`tightening_offsets` of many
    grasps): the shuffled controls deal from it instead of from this run's grasps; its monitors
    then need not run here."""
    scene = build_replay_scene(hand_dir, object_dir, params)
    data = mujoco.MjData(scene.model)
    slip = slip_sampler(scene, params)
    dt = float(params["timestep"])
    closing, upper = actuator_axes(scene, scene.model.nu)
    lead = float(labels["horizon_s"] if oracle_lead_s is None else oracle_lead_s)
    tables = [grasp_table] if isinstance(grasp_table, (str, Path)) else list(grasp_table)
    grasps = pl.concat([read_parquet(t) for t in tables], how="diagonal_relaxed")
    if grasp_ids is not None:
        grasps = grasps.filter(pl.col("grasp_id").is_in(list(grasp_ids)))
    if max_grasps is not None:
        grasps = grasps.sort("grasp_id").head(max_grasps)

    direct = [p for p in policies if p.kind not in ("none", "shuffled")]
    later = [p for p in policies if p.kind == "shuffled"]
    runs_of = [default_variant(p, reflex, debounce, arm_s) for p in direct] + list(variants)
    last = [default_variant(p, reflex, debounce, arm_s) for p in later]
    labels_seen = [v.label for v in [*runs_of, *last]]
    if len(set(labels_seen)) != len(labels_seen) or "none" in labels_seen:
        raise ValueError(f"closed loop: run labels must be unique and not 'none': {labels_seen}")
    monitors = {v.label for v in runs_of if v.policy.kind == "monitor"} | set(offset_pool or {})
    unknown = sorted({v.policy.of for v in last} - monitors)
    if unknown:
        raise ValueError(f"closed loop: shuffled controls of {unknown}, which are not monitor "
                         "policies of this run")  # fmt: skip

    def reflex_for(v: Variant, st: dict[str, Any], fire_step: int | None = None) -> Any:
        arm = arm_step_of(st["base"], arming, v.arm_s, window_steps, dt)
        return make_reflex(v.policy, v.reflex, closing, upper, dt, onset=st["base"].onset,
                           oracle_lead_steps=steps_of(lead, dt), arm_step=arm, stride=stride,
                           debounce=v.debounce, fresh=fresh, load_step=st["load_step"],
                           fire_step=fire_step)  # fmt: skip

    def run(v: Variant, st: dict[str, Any], g: dict[str, Any],
            fire_step: int | None = None) -> tuple[ReplayResult | None, Any, bool]:  # fmt: skip
        """One label's run of one grasp: (result, reflex, replayed); result None: the
        no-reflex run's (this reflex never moves the targets within it)."""
        grip = reflex_for(v, st, fire_step)
        if grip is None:
            return None, None, False
        if v.policy.kind == "monitor" and not acts_on(grip, st["base_run"].traces):
            return None, grip, False  # the scan saw every frame the loop would: no replay needed
        key = same_run_key(grip)
        if key is not None and key[0] >= st["base_run"].steps:
            # a schedule acting after the no-reflex run stopped: that run, step for step, stops
            # at the same place first, so the reflex never acts
            return None, grip, False
        if key is not None and key in st["done"]:
            return st["done"][key], grip, False  # the same tightening from the same step
        if key is None:  # release calm: the monitor stays in charge, replay it whole
            grip = reflex_for(v, st, fire_step)
            return replay_once(scene, data, g, object_id, params, grip, slip), grip, True
        # release never: until its first tightening the run is the no-reflex one and after it
        # nothing depends on the monitor, so a schedule tightening there, continued from the
        # no-reflex run's last fork before it, is the same run (replay.run.Fork)
        first = key[0]
        schedule = GripReflex(v.reflex, closing, upper, dt, fire_at=first)
        fork = st["forks"][max(f for f in st["forks"] if f <= first)]
        result = replay_once(scene, data, g, object_id, params, schedule, slip, start=fork,
                             prefix=st["base_run"].traces)  # fmt: skip
        st["done"][key] = result
        return result, grip, True

    swept = {v.label: (v.parameter, v.value) for v in [*runs_of, *last]}
    arm_of = {v.label: v.arm_s for v in [*runs_of, *last]}
    policy_of = {v.label: v.policy for v in [*runs_of, *last]}

    def row(gid: int, name: str, result: ReplayResult, grip: Any, base: Baseline,
            replayed: bool) -> dict[str, Any]:  # fmt: skip
        parameter, value = swept.get(name, ("", np.nan))
        pol = policy_of.get(name)
        monitored = pol is not None and pol.kind == "monitor"
        arm = arm_step_of(base, arming, arm_of.get(name, arm_s), window_steps, dt)
        return {"object": object_id, "grasp_id": gid, "policy": name, "parameter": parameter,
                "value": value, "stop_reason": result.stop_reason, "steps": result.steps,
                "threshold": float(pol.scorer.constants.threshold if pol.threshold is None  # type: ignore[union-attr]
                                   else pol.threshold) if monitored else np.nan,  # type: ignore[union-attr]
                "threshold_at_floor": bool(pol.at_floor) if monitored else False,  # type: ignore[union-attr]
                "threshold_never_warns": bool(pol.never_warns) if monitored else False,  # type: ignore[union-attr]
                "arm_s": arm * dt,
                # the run's seconds from arming to its end: a false alarm's exposure
                "armed_s": max(0, result.steps - arm) * dt,
                **outcome(result.traces, grip, base, labels, dt),
                "replayed": replayed}  # fmt: skip

    rows, traces, best = [], {}, -1
    rows_in = list(grasps.iter_rows(named=True))
    # what the shuffled controls need of each grasp once its own runs are done: its baseline,
    # its load step, each monitor's first tightening step and the no-reflex row (a control
    # whose grip never moves is that run)
    kept: list[dict[str, Any]] = []
    for i, g in enumerate(rows_in):
        gid = int(g["grasp_id"])
        start = time.perf_counter()
        forks: dict[int, Fork] = {}
        base_run = replay_once(scene, data, g, object_id, params, slip=slip, forks=forks)
        base = baseline_of(base_run.traces, labels, dt)
        st: dict[str, Any] = {"base_run": base_run, "base": base, "done": {}, "forks": forks,
                              "load_step": load_step_of(scene, params, object_id, gid)}
        mine = [row(gid, "none", base_run, None, base, True)]
        runs = {"none": base_run}
        first_on: dict[str, int | None] = {}
        for v in runs_of:
            result, grip, replayed = run(v, st, g)
            result = base_run if result is None else result
            mine.append(row(gid, v.label, result, grip, base, replayed))
            runs[v.label] = result
            first_on[v.label] = grip.on_steps[0] if grip is not None and grip.on_steps else None
        rows += mine
        if keep_traces:
            traces.update({(gid, k): r.traces for k, r in runs.items()})
        if timeline is not None and timeline in runs:
            rank = timeline_rank(next(r for r in mine if r["policy"] == timeline))
            if rank > best:
                best, traces = rank, {(gid, "none"): base_run.traces,
                                      (gid, timeline): runs[timeline].traces}  # fmt: skip
        kept.append({"base": base, "load_step": st["load_step"], "first_on": first_on,
                     "none_row": mine[0], "done": {},
                     # a shuffled control continues the no-reflex run from its forks
                     **({"base_run": base_run, "forks": forks} if last else {})})  # fmt: skip
        log.info("%s grasp %d (%d/%d): baseline %s; dropped under %s (%.1f s wall)", object_id,
                 gid, i + 1, len(rows_in),
                 "no verdict" if not base.usable else "fails" if base.failing else "holds",
                 ",".join(r["policy"] for r in mine if r["dropped"]) or "none",
                 time.perf_counter() - start)  # fmt: skip
    for v in last:  # each monitor's tightening offsets from arming, dealt to other grasps
        arms = [arm_step_of(k["base"], arming, v.arm_s, window_steps, dt) for k in kept]
        offsets = [None if k["first_on"].get(v.policy.of) is None
                   else k["first_on"][v.policy.of] - arm for k, arm in zip(kept, arms, strict=True)]
        if offset_pool is not None:
            offsets = list(offset_pool[v.policy.of])
        steps = shuffled_steps(offsets, arms, shuffle_seed, f"{object_id}/{v.label}")
        for g, k, step in zip(rows_in, kept, steps, strict=True):
            result, grip, replayed = run(v, k, g, step)
            if result is None:
                rows.append({**k["none_row"], "policy": v.label, "replayed": False,
                             **dict(zip(("parameter", "value"), swept[v.label], strict=True))})
            else:
                rows.append(row(int(g["grasp_id"]), v.label, result, grip, k["base"], replayed))
    return pl.DataFrame(rows), traces


def write_closed_loop(
    path: str | Path,
    table: pl.DataFrame,
    meta: dict[str, Any],
) -> None:
    """The per-object table (one row per grasp and policy), its settings in the metadata."""
    write_parquet(path, table, metadata={**meta, "mujoco_version": mujoco.__version__})


def write_timeline(
    path: str | Path, table: pl.DataFrame, traces: dict[tuple[int, str], dict[str, np.ndarray]]
) -> None:
    """The timeline grasp's two runs (``closed_loop_object(timeline=...)``) as one ``.npz``:
    ``none/<channel>`` and ``reflex/<channel>``, with the grasp's row of the reflex run (its
    times, rank) as ``meta`` (JSON); an empty ``meta`` when no run was kept."""
    arrays: dict[str, Any] = {}
    meta: dict[str, Any] = {}
    for (gid, label), channels in traces.items():
        side = "none" if label == "none" else "reflex"
        arrays.update({f"{side}/{c}": v for c, v in channels.items()})
        if side == "reflex":
            row = table.filter((pl.col("grasp_id") == gid) & (pl.col("policy") == label))
            meta = {k: (None if isinstance(v, float) and not np.isfinite(v) else v)
                    for k, v in row.row(0, named=True).items()}  # fmt: skip
            meta["rank"] = timeline_rank(row.row(0, named=True))
    save_npz(path, meta=np.array(json.dumps(meta)), **arrays)
