"""The replay's depth stop (replay.deep_stop): it fires exactly when a brute-force scan says it
should, only on replays 3.3.1's depth rule rejects whatever their settle index, and in
``run_replay`` it cuts the trace at the chunk where the run completes, changing nothing before."""

from __future__ import annotations

import numpy as np
import yaml
from conftest import CONFIG_DIR
from hypothesis import example, given, settings
from hypothesis import strategies as st

from graspstab.labels.interval import usable_interval
from graspstab.replay.grasp_setup import deep_stop
from graspstab.replay.run import DeepStop, run_replay
from graspstab.replay.sensors import sensor_layout
from tests.test_replay_sensors import SQUEEZE, TIPS, _placed

DT = 0.0005
LABELS = yaml.safe_load((CONFIG_DIR / "labels" / "default.yaml").read_text())
REPLAY = yaml.safe_load((CONFIG_DIR / "replay" / "default.yaml").read_text())


def _streamed(rule: DeepStop, dist: np.ndarray, chunks: list[int]) -> int | None:
    """Rows simulated when the stop fires, feeding ``dist`` in ``chunks`` as run_replay does."""
    carry, done = 0, 0
    for n in chunks:
        rows = dist[done : done + n]
        if len(rows) == 0:
            break
        hit, carry = rule.step(carry, done, rows)
        done += len(rows)
        if hit:
            return done
    return None


def _brute_force(rule: DeepStop, dist: np.ndarray) -> int | None:
    """The first row count e with rows [e - run, e) all deep and e - run >= after."""
    for end in range(rule.after + rule.run, len(dist) + 1):
        if all(dist[i] < rule.depth for i in range(end - rule.run, end)):  # NaN is not deep
            return end
    return None


@st.composite
def traces(draw: st.DrawFn) -> tuple[DeepStop, np.ndarray, list[int]]:
    run, after = draw(st.integers(1, 12)), draw(st.integers(0, 20))
    values = st.sampled_from([np.nan, -0.02, -0.009, -0.008, -0.007, 0.0, 0.001])
    # long deep stretches are what matter, so draw segments of one value
    segments = draw(st.lists(st.tuples(values, st.integers(1, 15)), min_size=1, max_size=8))
    dist = np.concatenate([np.full(k, v) for v, k in segments])
    chunks = draw(st.lists(st.integers(1, 9), min_size=1, max_size=40))
    chunks.append(len(dist))  # the rest, so every row is fed
    return DeepStop(-0.008, run, after), dist, chunks


@settings(max_examples=300, deadline=None)
@given(traces())
def test_stop_fires_at_the_first_chunk_end_after_the_run_completes(case) -> None:
    rule, dist, chunks = case
    expected = _brute_force(rule, dist)
    got = _streamed(rule, dist, chunks)
    if expected is None:
        assert got is None
    else:  # the chunk that holds row expected - 1 ends the replay
        ends = np.minimum(np.cumsum(chunks), len(dist))
        assert got == int(ends[np.searchsorted(ends, expected)])


def test_configured_rule_is_the_labelling_rule_in_steps() -> None:
    rule = deep_stop({**REPLAY, "timestep": DT})
    settle = LABELS["settle"]
    steps = round(settle["penetration_reject_s"] / DT)
    assert rule == DeepStop(settle["penetration_reject"], steps, round(settle["search_s"] / DT))
    assert deep_stop({**REPLAY, "deep_stop": {**REPLAY["deep_stop"], "enabled": False}}) is None


@settings(max_examples=60, deadline=None)
@given(
    deep_start=st.floats(0.0, 8.0),
    deep_s=st.floats(0.2, 3.0),
    quiet_at=st.floats(0.0, 3.5),
    chunk=st.sampled_from([200, 1000, 2000]),
)
@example(deep_start=3.5, deep_s=2.0, quiet_at=1.0, chunk=1000)  # fires at 4.5 s
@example(deep_start=2.5, deep_s=1.2, quiet_at=1.0, chunk=1000)  # 1.2 s deep, 0.7 s after 3 s
def test_a_stopped_replay_is_one_the_labelling_stage_rejects(deep_start, deep_s, quiet_at,
                                                             chunk) -> None:  # fmt: skip
    """On a 10 s trace with a deep stretch anywhere, settling anywhere (or never): whenever the
    stop fires, 3.3.1's rule rejects both the full trace and the cut one; when it does not fire
    on the full trace, neither decision depends on the stop."""
    n = round(10.0 / DT)
    t = np.arange(n) * DT
    dist = np.where(t < 0.3, -0.001 + 0.004 * (0.3 - t), -0.001)  # settles in distance at 0.3 s
    dist[(t >= deep_start) & (t < deep_start + deep_s)] = -0.012
    speed = np.where(t < quiet_at, 0.02, 0.001)
    rule = deep_stop({**REPLAY, "timestep": DT})
    stopped = _streamed(rule, dist, [chunk] * (n // chunk + 1))
    full = usable_interval(speed, dist, DT, LABELS["settle"], LABELS["contact_loss_s"])
    if deep_start >= 3.0 and deep_s >= 1.0 + 2 * DT:  # a full second after the settle search
        assert stopped is not None
    if stopped is None:
        return
    cut = usable_interval(speed[:stopped], dist[:stopped], DT, LABELS["settle"],
                          LABELS["contact_loss_s"])  # fmt: skip
    assert full.rejected == "depth" and cut.rejected == "depth"
    # the stretch covers whole rows of DT: it can hold one row more than deep_s / DT
    assert deep_start + deep_s >= REPLAY["deep_stop"]["after_s"] + 1.0 - DT - 1e-9


def test_run_replay_stops_too_deep_and_keeps_the_trace_before() -> None:
    """A held box (contact throughout) under a rule that counts any contact as deep: the run of
    300 rows from row 1000 completes inside the chunk [1000, 1500), which ends the replay."""
    model, data = _placed(SQUEEZE)
    layout = sensor_layout(model, tuple(TIPS), 8)
    full = run_replay(model, data, layout, 3000, 500, 400)
    model, data = _placed(SQUEEZE)
    cut = run_replay(model, data, layout, 3000, 500, 400, deep_stop=DeepStop(1.0, 300, 1000))
    assert (cut.stop_reason, cut.steps) == ("too_deep", 1500)
    for c in full.traces:
        np.testing.assert_array_equal(cut.traces[c], full.traces[c][:1500])
    # at the box's real depth (a fraction of a millimetre) the 3.3.1 rule never fires
    model, data = _placed(SQUEEZE)
    kept = run_replay(model, data, layout, 3000, 500, 400, deep_stop=DeepStop(-0.008, 300, 1000))
    assert (kept.stop_reason, kept.steps) == ("completed", 3000)
