"""A policy's outcome on planted traces: drops, onset, lead, latency, slip distance, grip cost."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import mujoco
import numpy as np
import polars as pl
import pytest
import yaml

from graspstab.closedloop.closed_loop import closed_loop_object, protocol_params, replay_once
from graspstab.closedloop.outcome import baseline_of, drop_step, outcome, slip_distance
from graspstab.closedloop.policies import Policy, actuator_axes, make_reflex
from graspstab.closedloop.reflex import ReflexParams
from graspstab.closedloop.sources import build_policies, latency_s
from graspstab.closedloop.sweep import sweep_variants
from graspstab.config.compose import compose_config
from graspstab.monitor.constants import MonitorConstants
from graspstab.replay.protocols import creep_free_replay, replay_params
from graspstab.replay.run import REFLEX
from graspstab.replay.scene import build_replay_scene

DT = 5e-4
LABELS = yaml.safe_load((Path(__file__).parents[1] / "config/labels/default.yaml").read_text())
T, SLIP, LOST = 8000, 5000, 5600  # the baseline slides at 1 cm/s from SLIP, loses contact at LOST


def traces(slip: int | None = None, lost: int | None = None, normal: float = 1.0,
           tightened: int | None = None) -> dict[str, np.ndarray]:  # fmt: skip
    """Planted channels: at rest with contact; sliding along x at 1 cm/s from ``slip``; no contact
    from ``lost``; fingertip normals of ``normal`` N each, 1.5 N from ``tightened`` on (with the
    reflex channel at 0.2 rad from there)."""
    vel = np.zeros((T, 3), np.float32)
    dist = np.full(T, -0.001, np.float32)
    if slip is not None:
        vel[slip:, 0] = 0.01
    if lost is not None:
        dist[lost:] = np.nan
    force = np.full((T, 5), normal, np.float32)
    reflex = np.zeros(T, np.float32)
    if tightened is not None:
        force[tightened:] = 1.5
        reflex[tightened:] = 0.2
    return {"velocity": vel, "min_distance": dist, "normal": force, "shear": force * 0.1,
            REFLEX: reflex}  # fmt: skip


def test_drop_is_the_first_long_enough_run_without_contact() -> None:
    dist = np.zeros(1000)
    dist[100:250] = np.nan  # 150 steps: shorter than 0.1 s (200)
    dist[400:700] = np.nan
    assert drop_step(dist, 200) == 400
    assert drop_step(np.zeros(1000), 200) is None


def test_slip_distance_runs_from_onset_to_arrest() -> None:
    speed = np.zeros(2000)
    speed[500:600] = 0.01
    dist, arrest = slip_distance(speed, 500, 2000, 0.0012, 300, DT)
    assert dist == pytest.approx(100 * 0.01 * DT) and arrest == 600
    dist, arrest = slip_distance(np.full(2000, 0.01), 500, 1500, 0.0012, 300, DT)
    assert dist == pytest.approx(1000 * 0.01 * DT) and arrest is None


def test_a_saved_grasp_against_its_failing_baseline() -> None:
    base = baseline_of(traces(SLIP, LOST), LABELS, DT)
    assert base.usable and base.onset == SLIP and base.drop == LOST and base.end == LOST
    none = outcome(traces(SLIP, LOST), None, base, LABELS, DT)
    assert none["dropped"] and none["failing"] and not none["fired"] and not none["prevented"]
    assert none["slip_mm"] == pytest.approx(600 * 0.01 * DT * 1e3) and np.isnan(none["arrest_s"])
    # warned at 4779, tightened from 4800; the object stays put and in contact
    saved = outcome(traces(tightened=4800), SimpleNamespace(warn_frames=[4779]), base, LABELS, DT)
    assert saved["prevented"] and not saved["dropped"] and not saved["false_alarm"]
    assert saved["lead_s"] == pytest.approx((SLIP - 4779) * DT)
    assert saved["latency_s"] == pytest.approx((4800 - SLIP) * DT)  # tightened before the onset
    assert saved["tightened_s"] == pytest.approx((T - 4800) * DT)
    assert saved["slip_mm"] == 0 and saved["arrest_s"] == pytest.approx(SLIP * DT)
    # 5 fingertips x 0.5 N more, while both runs hold the object: [4800, LOST)
    assert saved["added_normal_mean_n"] == pytest.approx(2.5)
    assert saved["added_normal_peak_n"] == pytest.approx(2.5)


def test_false_alarms_and_worse_outcomes_on_a_holding_grasp() -> None:
    base = baseline_of(traces(), LABELS, DT)
    assert base.usable and base.onset is None and base.drop is None
    alarm = outcome(traces(tightened=3000), SimpleNamespace(warn_frames=[2979]), base, LABELS, DT)
    assert alarm["false_alarm"] and not alarm["worse"] and np.isnan(alarm["lead_s"])
    assert np.isnan(alarm["latency_s"]) and np.isnan(alarm["slip_mm"])
    pushed = outcome(traces(tightened=3000, lost=3500), SimpleNamespace(warn_frames=[2979]), base,
                     LABELS, DT)  # fmt: skip
    assert pushed["worse"] and pushed["dropped"] and pushed["drop_s"] == pytest.approx(3500 * DT)
    # the grip cost stops where the tightened run lost the object
    assert pushed["added_normal_mean_n"] == pytest.approx(2.5)


# ---------------------------------------------------------------------------------------------
# the per-object runner on the real hand and a real object, and the policies from a run's files


def test_closed_loop_object_runs_every_policy_on_the_same_grasp(
    foam_brick_dir: Path, built_hand_dir: Path, tmp_path: Path
) -> None:
    cfg = compose_config(Path(__file__).parents[1] / "config", [])
    params = dict(protocol_params(cfg, "reference"), steps=1200)
    quat = np.array([0.9, 0.2, -0.3, 0.25])
    quat /= np.linalg.norm(quat)
    grasp = {"grasp_id": 7, "shard": 0, "wrist_x": 0.3, "wrist_y": -0.1, "wrist_z": 0.05,
             **{f"quat_{a}": float(v) for a, v in zip("wxyz", quat, strict=True)},
             **{f"theta_{k:02d}": 0.0 for k in range(16)}}  # fmt: skip
    pl.DataFrame([grasp]).write_parquet(tmp_path / "grasps.parquet")
    policies = build_policies(["none", "always", "oracle"])
    table, traces = closed_loop_object(
        "061_foam_brick", foam_brick_dir, built_hand_dir, tmp_path / "grasps.parquet", params,
        cfg["labels"], policies, ReflexParams(amount=0.2, rate=4.0, delay_s=0.01),
        keep_traces=True, variants=sweep_variants([policies[1]], {"amount": [0.1]},
                                                  ReflexParams(0.2, 4.0, 0.01), 1, 0.0),
    )  # fmt: skip
    swept = table.filter(pl.col("policy") == "always@amount=0.1").row(0, named=True)
    assert swept["parameter"] == "amount" and swept["value"] == 0.1
    assert swept["peak_offset_rad"] == pytest.approx(0.1)
    table = table.filter(pl.col("parameter") == "")
    assert table["policy"].to_list() == ["none", "always", "oracle"]
    rows = {r["policy"]: r for r in table.iter_rows(named=True)}
    # far from the hand the object falls at once: every policy drops it, none prevents a drop
    assert all(r["dropped"] and not r["prevented"] for r in rows.values())
    assert not rows["none"]["fired"] and rows["always"]["fired"]
    assert rows["always"]["tighten_s"] == 0
    assert rows["always"]["peak_offset_rad"] == pytest.approx(0.2)
    # the grip reached 0.2 rad at 4 rad/s after 50 ms (100 steps) and stayed there
    offset = traces[(7, "always")][REFLEX]
    np.testing.assert_allclose(offset[:100], 4.0 * DT * np.arange(1, 101), rtol=1e-5)
    assert np.all(offset[100:] == pytest.approx(0.2))
    assert REFLEX not in traces[(7, "none")]  # the open loop records no reflex channel
    with pytest.raises(ValueError, match="kind 'sometimes'"):
        Policy("x", "sometimes")


def test_latency_is_the_latency_studys_median_of_the_family_and_window(tmp_path: Path) -> None:
    pl.DataFrame({"study": ["baseline", "sweep", "sweep"], "family": ["lstm", "lstm", "gru"],
                  "window_steps": [400, 20, 20], "median_ms": [2.0, 0.4, 0.9]}
                 ).write_parquet(tmp_path / "latency.parquet")  # fmt: skip
    assert latency_s(tmp_path / "latency.parquet", "lstm", 20) == pytest.approx(0.4e-3)
    with pytest.raises(ValueError, match="no latency row for family 'cnn' at 20 steps"):
        latency_s(tmp_path / "latency.parquet", "cnn", 20)


def test_protocol_params_are_the_replay_stages_but_for_the_closed_loops_ramp_path() -> None:
    cfg = compose_config(Path(__file__).parents[1] / "config", [])
    assert protocol_params(cfg, "reference") == replay_params(cfg["replay"])
    assert "ramp" not in protocol_params(cfg, "reference")  # gravity: the ramp does not count
    bench, loop = creep_free_replay(cfg), protocol_params(cfg, "creep_free")
    assert loop["ramp"] == {**bench["ramp"], "path": cfg["closed_loop"]["ramp_path"]}
    assert {k: v for k, v in loop.items() if k != "ramp"} == {
        k: v for k, v in bench.items() if k != "ramp"
    }
    assert loop["protocol"] == "ramp" and loop["contact"] == cfg["creep_free"]["contact"]
    with pytest.raises(ValueError, match="unknown protocol 'slip'"):
        protocol_params(cfg, "slip")


def test_max_grasps_keeps_the_lowest_ids(
    foam_brick_dir: Path, built_hand_dir: Path, tmp_path: Path
) -> None:
    cfg = compose_config(Path(__file__).parents[1] / "config", [])
    params = dict(protocol_params(cfg, "reference"), steps=200)
    grasp = {"shard": 0, "wrist_x": 0.3, "wrist_y": -0.1, "wrist_z": 0.05,
             **{f"quat_{a}": v for a, v in zip("wxyz", (1.0, 0.0, 0.0, 0.0), strict=True)},
             **{f"theta_{k:02d}": 0.0 for k in range(16)}}  # fmt: skip
    pl.DataFrame([dict(grasp, grasp_id=i) for i in (9, 3, 5)]).write_parquet(tmp_path / "g.parquet")
    table, traces = closed_loop_object(
        "061_foam_brick", foam_brick_dir, built_hand_dir, tmp_path / "g.parquet", params,
        cfg["labels"], build_policies(["none"]), ReflexParams(0.2, 4.0, 0.01), max_grasps=2,
    )  # fmt: skip
    assert table["grasp_id"].to_list() == [3, 5] and traces == {}


class Constant:
    """A scorer that gives every window the same probability."""

    def __init__(self, p: float, window: int = 20) -> None:
        self.p = p
        self.constants = MonitorConstants(np.zeros((5, 2)), np.ones((5, 2)), 0.5, window)

    def score_one(self, window: np.ndarray) -> float:
        return self.p

    def __call__(self, windows: np.ndarray) -> np.ndarray:
        return np.full(len(windows), self.p)


def test_a_monitor_that_never_acts_reuses_the_no_reflex_run_and_matches_its_replay(
    foam_brick_dir: Path, built_hand_dir: Path, tmp_path: Path
) -> None:
    cfg = compose_config(Path(__file__).parents[1] / "config", [])
    params = dict(protocol_params(cfg, "reference"), steps=600)
    grasp = {"grasp_id": 1, "shard": 0, "wrist_x": 0.3, "wrist_y": -0.1, "wrist_z": 0.05,
             **{f"quat_{a}": v for a, v in zip("wxyz", (1.0, 0.0, 0.0, 0.0), strict=True)},
             **{f"theta_{k:02d}": 0.0 for k in range(16)}}  # fmt: skip
    pl.DataFrame([grasp]).write_parquet(tmp_path / "g.parquet")
    calm, alarmed = Policy("calm", "monitor", Constant(0.1)), Policy("alarmed", "monitor",
                                                                   Constant(0.9))  # fmt: skip
    twin = Policy("twin", "monitor", Constant(0.8))  # warns on the same frame as alarmed
    reflex = ReflexParams(0.2, 4.0, 0.01)
    table, traces = closed_loop_object(
        "061_foam_brick", foam_brick_dir, built_hand_dir, tmp_path / "g.parquet", params,
        cfg["labels"], [Policy("none", "none"), calm, alarmed, twin], reflex, keep_traces=True,
    )  # fmt: skip
    rows = {r["policy"]: r for r in table.iter_rows(named=True)}
    assert not rows["calm"]["replayed"] and not rows["calm"]["fired"]
    assert rows["alarmed"]["replayed"] and rows["alarmed"]["fired"]
    # the same tightening from the same step is the same run: reused, not replayed
    assert not rows["twin"]["replayed"] and traces[(1, "twin")] is traces[(1, "alarmed")]
    # no wall time in the table (a run-time measurement: in the job's log, never in its data)
    assert not any("wall" in k for k in rows["twin"])
    same = {k for k in rows["twin"] if k not in ("policy", "replayed")}
    assert all(rows["twin"][k] == pytest.approx(rows["alarmed"][k], nan_ok=True) for k in same)
    # the calm monitor in the loop, replayed for real, gives the same row and traces
    scene = build_replay_scene(built_hand_dir, foam_brick_dir, params)
    closing, upper = actuator_axes(scene, scene.model.nu)
    grip = make_reflex(calm, reflex, closing, upper, float(params["timestep"]))
    run = replay_once(scene, mujoco.MjData(scene.model), grasp, "061_foam_brick", params, grip)
    base = baseline_of(traces[(1, "none")], cfg["labels"], float(params["timestep"]))
    real = outcome(run.traces, grip, base, cfg["labels"], float(params["timestep"]))
    for k, v in real.items():
        assert rows["calm"][k] == pytest.approx(v, nan_ok=True), k
    n = min(run.steps, rows["none"]["steps"])
    np.testing.assert_array_equal(run.traces["normal"][:n], traces[(1, "calm")]["normal"][:n])
