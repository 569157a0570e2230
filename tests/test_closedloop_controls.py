"""The closed loop's arming and controls: every monitor armed at the settle index plus the
window, the load-onset controller firing where the protocol's load starts, oracles at their
leads, and each monitor's shuffled control keeping its own tightening times from arming."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import mujoco
import numpy as np
import polars as pl
import pytest

from graspstab.closedloop.closed_loop import (
    arm_step_of,
    closed_loop_object,
    load_step_of,
    protocol_params,
    replay_once,
    shuffled_steps,
)
from graspstab.closedloop.outcome import Baseline
from graspstab.closedloop.policies import Policy, policy_names
from graspstab.closedloop.reflex import ReflexParams
from graspstab.closedloop.sources import build_policies
from graspstab.closedloop.summary import default_comparisons, is_control
from graspstab.config.compose import compose_config
from graspstab.replay.grasp_setup import grasp_load
from graspstab.replay.scene import build_replay_scene
from tests.test_closedloop_outcome import Constant

DT = 5e-4
CONFIG = Path(__file__).parents[1] / "config"


def _base(usable: bool, start: int) -> Baseline:
    return Baseline(usable, start, start + 1000, None, None, np.zeros(2000))


def test_arming_at_the_settle_index_plus_the_window_never_before_arm_s() -> None:
    assert arm_step_of(_base(True, 300), "settle", 0.0, 20, DT) == 319
    assert arm_step_of(_base(True, 300), "settle", 1.0, 20, DT) == 2000  # not before arm_s
    assert arm_step_of(_base(True, 300), "fixed", 0.05, 20, DT) == 100
    assert arm_step_of(_base(False, 300), "settle", 0.05, 20, DT) == 100  # no verdict: arm_s
    with pytest.raises(ValueError, match="settle or fixed"):
        arm_step_of(_base(True, 300), "sometimes", 0.0, 20, DT)


def test_the_shuffled_control_keeps_the_monitors_timing_distribution() -> None:
    offsets = [5, None, 40, 5, 300, None, 12]
    arms = [100, 200, 300, 400, 500, 600, 700]
    steps = shuffled_steps(offsets, arms, 0, "obj/gru~shuffled")
    dealt = [None if s is None else s - a for s, a in zip(steps, arms, strict=True)]
    assert Counter(dealt) == Counter(offsets)  # the same offsets from arming, dealt anew
    assert dealt != offsets  # and dealt to other grasps (this seed moves them)
    assert steps == shuffled_steps(offsets, arms, 0, "obj/gru~shuffled")  # reproducible
    assert steps != shuffled_steps(offsets, arms, 0, "obj/cnn~shuffled")  # per monitor


def test_tightening_offsets_pool_and_dealing_without_replacement() -> None:
    """The pool: each monitor's first tightening from arming over the usable grasps (None where
    it never tightened); dealt from a larger pool, each grasp gets a different entry."""
    from graspstab.closedloop.closed_loop import tightening_offsets

    t = pl.DataFrame({
        "policy": ["none", "gru", "gru", "gru", "always"],
        "usable": [True, True, True, False, True],
        "parameter": [""] * 5, "threshold": [np.nan, 0.5, 0.5, 0.5, np.nan],
        "tighten_s": [np.nan, 0.30, np.nan, 0.9, 0.1], "arm_s": [0.1, 0.1, 0.2, 0.1, 0.1],
    })  # fmt: skip
    assert tightening_offsets(t, DT) == {"gru": [400, None]}
    pool = list(range(100, 120))
    steps = shuffled_steps(pool, [1000, 2000, 3000], 0, "o/gru~shuffled")
    dealt = [s - a for s, a in zip(steps, [1000, 2000, 3000], strict=True)]
    assert len(set(dealt)) == 3 and set(dealt) <= set(pool)
    with pytest.raises(ValueError, match="2 tightening offsets to deal to 3 grasps"):
        shuffled_steps([1, 2], [0, 0, 0], 0, "k")


def test_policy_names_and_comparisons_cover_the_controls() -> None:
    names = policy_names(["none", "always", "oracle", "load_onset", "proxy", "gru"],
                         [0.0, 0.05, 0.15], shuffled=True)  # fmt: skip
    assert names == ["none", "always", "oracle-0ms", "oracle-50ms", "oracle-150ms",
                     "load_onset", "proxy", "gru", "proxy~shuffled", "gru~shuffled"]
    built = [p.name for p in build_policies(["none", "always", "oracle", "load_onset"],
                                            oracle_leads_s=[0.0, 0.05, 0.15], shuffled=True)]
    assert built == names[:6]
    assert [n for n in names if not is_control(n)] == ["proxy", "gru"]
    pairs = default_comparisons(names)
    assert ("gru", "proxy") in pairs and ("gru", "gru~shuffled") in pairs
    assert ("proxy", "proxy~shuffled") in pairs and ("oracle-0ms", "proxy") not in pairs
    with pytest.raises(ValueError, match="names the monitor it shuffles"):
        Policy("x~shuffled", "shuffled")
    # each monitor at both thresholds (the pick has no budget threshold), each with its control
    names = policy_names(["none", "proxy", "gru", "pick"], [], shuffled=True,
                         thresholds=["recall", "budget"])  # fmt: skip
    assert names == ["none", "proxy", "proxy-budget", "gru", "gru-budget", "pick",
                     "proxy~shuffled", "proxy-budget~shuffled", "gru~shuffled",
                     "gru-budget~shuffled", "pick~shuffled"]  # fmt: skip
    pairs = default_comparisons(names)
    assert ("gru-budget", "proxy-budget") in pairs and ("gru", "proxy") in pairs
    assert ("gru-budget", "proxy") not in pairs and ("pick", "proxy") in pairs


def test_budget_thresholds_need_the_grasp_level_evaluations_window() -> None:
    from graspstab.config import load_config
    from graspstab.config.errors import ConfigError

    schema = CONFIG.parent / "workflow" / "schemas" / "config.schema.yaml"
    on = {"closed_loop": {"enabled": True, "protocols": ["reference"], "window_s": 0.05}}
    with pytest.raises(ConfigError, match="closed_loop.thresholds holds budget"):
        load_config(CONFIG, schema, on, check_files=False)
    on["overrides"] = ["closed_loop.thresholds=[recall]"]
    assert load_config(CONFIG, schema, on, check_files=False)["closed_loop"]["thresholds"] == [
        "recall"]


def test_controls_on_real_replays_under_the_disturbance(
    foam_brick_dir: Path, built_hand_dir: Path, tmp_path: Path
) -> None:
    """Three grasps far from the hand under the hidden-onset disturbance (delays 0.1-0.2 s):
    the load-onset controller tightens at the step the replay's own load starts; a monitor that
    always warns tightens after arming plus its delay, and its shuffled control at the same
    offset from arming (every grasp's offset is the same); a monitor that never warns leaves
    its shuffled control the no-reflex run. (Not fresh: a monitor warning from its first score
    is up at arming, and a fresh one would never fire.)"""
    cfg = compose_config(CONFIG, ["creep_free.load=perturb",
                                  "replay.perturb.delay_s=[0.1,0.2]"])  # fmt: skip
    params = dict(protocol_params(cfg, "creep_free"), steps=800)
    assert params["protocol"] == "perturb"
    grasp = {"shard": 0, "wrist_x": 0.3, "wrist_y": -0.1, "wrist_z": 0.05,
             **{f"quat_{a}": v for a, v in zip("wxyz", (1.0, 0.0, 0.0, 0.0), strict=True)},
             **{f"theta_{k:02d}": 0.0 for k in range(16)}}  # fmt: skip
    pl.DataFrame([dict(grasp, grasp_id=i) for i in (1, 2, 3)]).write_parquet(tmp_path / "g.pq")
    policies = [Policy("none", "none"), Policy("load_onset", "load_onset"),
                Policy("alarmed", "monitor", Constant(0.9)), Policy("calm", "monitor",
                Constant(0.1)), Policy("alarmed~shuffled", "shuffled", of="alarmed"),
                Policy("calm~shuffled", "shuffled", of="calm")]  # fmt: skip
    table, _ = closed_loop_object(
        "061_foam_brick", foam_brick_dir, built_hand_dir, tmp_path / "g.pq", params,
        cfg["labels"], policies, ReflexParams(0.2, 4.0, 0.01), stride=10, arm_s=0.05,
        arming="settle", window_steps=20,
    )  # fmt: skip
    rows = {(r["grasp_id"], r["policy"]): r for r in table.iter_rows(named=True)}
    scene = build_replay_scene(built_hand_dir, foam_brick_dir, params)
    for gid in (1, 2, 3):
        # the load the replay draws for this grasp starts where the controller tightened
        replay_once(scene, mujoco.MjData(scene.model), dict(grasp, grasp_id=gid),
                    "061_foam_brick", params)  # places the grasp: gravity in the hand frame
        load = grasp_load(params, scene, scene.model.opt.gravity.copy(), "061_foam_brick", gid)
        step = load_step_of(scene, params, "061_foam_brick", gid)
        assert step == round(load.start_s / DT) and 200 <= step <= 400
        assert rows[(gid, "load_onset")]["tighten_s"] == pytest.approx(step * DT)
        # armed at arm_s (no usable interval far from the hand); fires after the delay
        alarmed = rows[(gid, "alarmed")]
        assert alarmed["arm_s"] == pytest.approx(0.05) and alarmed["fired"]
        assert rows[(gid, "alarmed~shuffled")]["tighten_s"] == pytest.approx(alarmed["tighten_s"])
        calm = rows[(gid, "calm~shuffled")]
        assert not calm["fired"] and not calm["replayed"]
        assert calm["dropped"] == rows[(gid, "none")]["dropped"]


def test_fold_policies_come_from_the_folds_own_files(tmp_path: Path) -> None:
    """build_fold_policies: the family's fold model at its own threshold, the proxy's threshold
    chosen on the fold's validation objects' windows (not the dataset's split), the budget
    thresholds of the fold's thresholds.json (a never-warning one flagged), the rows in
    policy_names' order; the pick refused."""
    import torch

    from graspstab.closedloop.sources import build_fold_policies
    from graspstab.evaluation.tested_run import train_and_test
    from graspstab.learning.data import load_window_data
    from graspstab.monitor.proxy import select_proxy_threshold
    from tests.test_learning_train import LSTM, TRAIN, write_dataset

    torch.set_num_threads(1)
    data = write_dataset(tmp_path / "d", {"train": 8, "val": 8, "test": 8})
    run = tmp_path / "run"
    train_and_test(data, LSTM, {**TRAIN, "max_epochs": 1, "patience": 1}, 0, run)
    index = pl.read_parquet(data / "index.parquet")
    objects = sorted(set(index["object"]))
    assignment = {o: ("val" if o == objects[-1] else "train") for o in objects}
    pl.DataFrame({"study": ["sweep"], "family": ["lstm"], "window_steps": [20],
                  "median_ms": [0.5]}).write_parquet(tmp_path / "latency.parquet")  # fmt: skip
    choice = {"threshold": 0.7, "at_floor": False, "never_warns": False}
    folds = {"thresholds": {"lstm": choice, "proxy": {**choice, "threshold": 0.51,
                                                       "never_warns": True}}}  # fmt: skip
    rule = {"rule": "min_recall", "min_recall": 0.9}
    names = ["none", "oracle", "proxy", "lstm"]
    pols = build_fold_policies(
        names, checkpoints={"lstm": (run / "model.pt", run / "metrics.json")},
        fold_thresholds=folds, proxy_dataset=data, assignment=assignment, threshold=rule,
        latency_table=tmp_path / "latency.parquet", oracle_leads_s=[0.0, 0.05], shuffled=True,
        thresholds=["recall", "budget"],
    )  # fmt: skip
    assert [p.name for p in pols] == policy_names(names, [0.0, 0.05], True, ["recall", "budget"])
    by = {p.name: p for p in pols}
    w = load_window_data(data)
    rows = np.flatnonzero(index["object"].to_numpy() == objects[-1])
    want = select_proxy_threshold(w.windows[rows], w.labels(rows), rule)["threshold"]
    assert by["proxy"].threshold == pytest.approx(want)
    assert by["lstm-budget"].threshold == 0.7 and by["lstm"].threshold != 0.7
    assert by["proxy-budget"].never_warns and not by["lstm-budget"].never_warns
    assert by["lstm"].latency_s == pytest.approx(0.5e-3)
    with pytest.raises(ValueError, match="the pick is an export"):
        build_fold_policies(["pick"], checkpoints={}, fold_thresholds=folds, proxy_dataset=data,
                            assignment=assignment, threshold=rule,
                            latency_table=tmp_path / "latency.parquet")  # fmt: skip


def test_a_replay_continued_from_a_fork_is_the_full_replay(
    foam_brick_dir: Path, built_hand_dir: Path
) -> None:
    """Under the disturbance (its load copied at the fork), a reflex that tightens at step 1300
    replayed from placement and continued from the no-reflex run's fork at 1200 give the same
    rows, bit for bit, and end alike; a monitor-driven reflex cannot be continued."""
    from graspstab.closedloop.policies import actuator_axes, make_reflex
    from graspstab.closedloop.reflex import GripReflex
    from graspstab.replay.grasp_setup import slip_sampler

    cfg = compose_config(CONFIG, ["creep_free.load=perturb", "replay.perturb.delay_s=[0.1,0.2]"])
    # far from the hand the object falls free: no contact-loss stop, so every chunk runs
    params = dict(protocol_params(cfg, "creep_free"), steps=2000, chunk_steps=400,
                  stop_after_loss_s=10.0)
    grasp = {"grasp_id": 4, "shard": 0, "wrist_x": 0.3, "wrist_y": -0.1, "wrist_z": 0.05,
             **{f"quat_{a}": v for a, v in zip("wxyz", (1.0, 0.0, 0.0, 0.0), strict=True)},
             **{f"theta_{k:02d}": 0.0 for k in range(16)}}  # fmt: skip
    scene = build_replay_scene(built_hand_dir, foam_brick_dir, params)
    data, slip = mujoco.MjData(scene.model), slip_sampler(scene, params)
    closing, upper = actuator_axes(scene, scene.model.nu)
    reflex = ReflexParams(0.2, 4.0, 0.01)
    forks: dict = {}
    base = replay_once(scene, data, grasp, "061_foam_brick", params, slip=slip, forks=forks)
    assert sorted(forks)[:4] == [0, 400, 800, 1200]

    def grip() -> GripReflex:
        return make_reflex(Policy("x", "shuffled", of="m"), reflex, closing, upper, DT,
                           fire_step=1300)  # fmt: skip

    full = replay_once(scene, data, grasp, "061_foam_brick", params, grip(), slip)
    cont = replay_once(scene, data, grasp, "061_foam_brick", params, grip(), slip,
                       start=forks[1200], prefix=base.traces)  # fmt: skip
    assert (cont.steps, cont.stop_reason) == (full.steps, full.stop_reason)
    assert set(cont.traces) == set(full.traces)
    for c, v in full.traces.items():
        np.testing.assert_array_equal(cont.traces[c], v, err_msg=c)
    assert full.traces["reflex"][1299] == 0 and full.traces["reflex"][1300] > 0
    monitored = make_reflex(Policy("m", "monitor", Constant(0.9)), reflex, closing, upper, DT)
    with pytest.raises(ValueError, match="cannot start mid-replay"):
        replay_once(scene, data, grasp, "061_foam_brick", params, monitored, slip,
                    start=forks[1200], prefix=base.traces)  # fmt: skip
