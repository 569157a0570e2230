"""The fingertip sensor model (graspstab.sensing.sensor_model): each corruption checked against an
independent numpy computation on synthetic force traces of shape (B, T, F, C)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from graspstab.sensing.sensor_model import CORRUPTIONS, SensorModel, SensorModelError, sense

DT = 5e-4  # the simulator grid: 2 kHz
SCALE = np.array([[0.5, 1.0, 2.0], [3.0, 4.0, 6.0]])  # (F, C) distinct channel stds


def _rng(seed: int = 0) -> np.random.Generator:
    return np.random.default_rng(seed)


def _ramp(b: int, t: int, f: int = 1, c: int = 1) -> np.ndarray:
    """A strictly increasing trace whose value at frame i is i (exact in float32)."""
    return np.broadcast_to(np.arange(t, dtype=np.float64)[None, :, None, None], (b, t, f, c))


def _runs(row: np.ndarray) -> np.ndarray:
    """Lengths of the complete constant runs of a 1-D array (the first and last partial ones
    dropped)."""
    starts = np.flatnonzero(np.diff(row) != 0) + 1
    return np.diff(starts)


# --- identity ------------------------------------------------------------------------------------


def test_default_sensor_is_identity():
    """SensorModel() returns the last W frames unchanged as float32 and reports is_identity."""
    seg = _rng(1).normal(size=(3, 50, 2, 3)) * 10
    sensor = SensorModel()
    out = sense(sensor, seg, 20, SCALE, DT, _rng())
    assert sensor.is_identity
    assert out.dtype == np.float32
    assert out.shape == (3, 20, 2, 3)
    np.testing.assert_array_equal(out, seg[:, -20:].astype(np.float32))


def test_full_scale_alone_keeps_identity():
    """A converter range without bits (no quantisation) is still the identity."""
    assert SensorModel(full_scale_n=5.0).is_identity


@pytest.mark.parametrize(
    "settings",
    [
        {"noise": 0.1},
        {"gain": 0.1},
        {"drift": 0.5},
        {"bits": 4, "full_scale_n": 50.0},
        {"rate_hz": 100.0},
        {"delay_s": 0.01},
        {"drop": 0.3},
    ],
    ids=lambda s: next(iter(s)),
)
def test_any_single_corruption_is_not_identity(settings):
    """One nonzero corruption clears is_identity and changes the output of a varied trace."""
    sensor = SensorModel(**settings)
    assert not sensor.is_identity
    t, w = 200, 100
    seg = _ramp(4, t, 2, 3) * 0.37 + _rng(2).normal(size=(4, t, 2, 3))
    out = sense(sensor, seg, w, SCALE, DT, _rng())
    assert not np.array_equal(out, seg[:, -w:].astype(np.float32))


def test_corruption_table_names_real_fields():
    """Every CORRUPTIONS entry names a SensorModel field whose default is the off value."""
    off = SensorModel()
    for name, field in CORRUPTIONS.items():
        assert hasattr(off, field), name
    assert set(CORRUPTIONS) == {"noise", "gain", "drift", "quantisation", "rate", "delay", "drop"}


# --- noise ---------------------------------------------------------------------------------------


def test_noise_std_is_noise_times_channel_scale():
    """On a constant input at full rate the residual per channel has mean 0, std noise*scale,
    and is white (no lag-1 correlation)."""
    noise, b, w = 0.2, 200, 200
    seg = np.full((b, w, 2, 3), 5.0)
    out = sense(SensorModel(noise=noise), seg, w, SCALE, DT, _rng(3))
    res = out.astype(np.float64) - 5.0
    std = res.std(axis=(0, 1))
    np.testing.assert_allclose(std, noise * SCALE, rtol=0.03)
    n = b * w
    assert np.all(np.abs(res.mean(axis=(0, 1))) < 4 * noise * SCALE / math.sqrt(n))
    z = res / (noise * SCALE)
    lag1 = (z[:, 1:] * z[:, :-1]).mean(axis=(0, 1))
    assert np.all(np.abs(lag1) < 0.03)


# --- gain ----------------------------------------------------------------------------------------


def test_gain_is_constant_per_window_channel_with_std_gain():
    """Noise-free gain: output/input is constant over time per (window, fingertip, channel) and
    (ratio - 1) across windows has mean 0 and std gain, independently per channel."""
    gain, b, t = 0.05, 4000, 30
    time = np.arange(t) * DT
    seg = 2.0 + np.sin(2 * np.pi * 40 * time)[None, :, None, None] + np.zeros((b, t, 2, 3))
    seg = seg + 0.5 * np.arange(6).reshape(1, 1, 2, 3)
    out = sense(SensorModel(gain=gain), seg, t, SCALE, DT, _rng(4))
    ratio = out.astype(np.float64) / seg
    spread = ratio.max(axis=1) - ratio.min(axis=1)
    assert spread.max() < 1e-5
    g = ratio[:, 0] - 1.0  # (B, F, C)
    np.testing.assert_allclose(g.std(axis=0), gain, rtol=0.05)
    assert np.all(np.abs(g.mean(axis=0)) < 4 * gain / math.sqrt(b))
    corr = np.corrcoef(g.reshape(b, -1).T)
    assert np.all(np.abs(corr[np.triu_indices(6, 1)]) < 0.1)


# --- drift ---------------------------------------------------------------------------------------


def test_drift_is_linear_from_zero_at_segment_start():
    """On zero input the bias is linear in time, zero at the segment's first frame, and its slope
    across windows has std drift*scale per second."""
    drift, b, t, w = 0.5, 3000, 60, 20
    seg = np.zeros((b, t, 2, 3))
    out = sense(SensorModel(drift=drift), seg, w, SCALE, DT, _rng(5)).astype(np.float64)
    tw = np.arange(w) * DT  # time from the window's first frame
    y = out.transpose(1, 0, 2, 3).reshape(w, -1)
    slope, icpt = np.polyfit(tw, y, 1)
    fit = slope[None] * tw[:, None] + icpt[None]
    assert np.abs(y - fit).max() <= 1e-6 * np.abs(y).max()
    # the window is the last W frames: its start lies (T - W) frames after the tare
    np.testing.assert_allclose(icpt, slope * (t - w) * DT, rtol=1e-4, atol=1e-9)
    # extrapolated to the segment's first frame the bias is zero
    assert np.abs(icpt - slope * (t - w) * DT).max() < 1e-6 * np.abs(y).max()
    slope = slope.reshape(b, 2, 3)
    np.testing.assert_allclose(slope.std(axis=0), drift * SCALE, rtol=0.05)
    assert np.all(np.abs(slope.mean(axis=0)) < 4 * drift * SCALE / math.sqrt(b))


# --- quantisation --------------------------------------------------------------------------------


@pytest.mark.parametrize(("bits", "fs"), [(6, 10.0), (8, 100.0), (3, 1.5)])
def test_quantisation_levels_error_and_clipping(bits, fs):
    """Outputs are integer multiples of 2*FS/2**bits, within half a step inside the range, and
    clipped to +-FS beyond it."""
    step = 2 * fs / 2**bits
    x = np.linspace(-1.7 * fs, 1.7 * fs, 5001)
    seg = x[None, :, None, None]
    out = sense(SensorModel(bits=bits, full_scale_n=fs), seg, x.size, 1.0, DT, _rng())
    y = out[0, :, 0, 0].astype(np.float64)
    k = y / step
    np.testing.assert_allclose(k, np.round(k), atol=1e-4)
    inside = np.abs(x) <= fs
    assert np.all(np.abs(y[inside] - x[inside]) <= step / 2 + 1e-6 * fs)
    np.testing.assert_array_equal(y[x > fs], fs)
    np.testing.assert_array_equal(y[x < -fs], -fs)
    assert np.all(np.abs(y) <= fs)


# --- rate (zero-order hold) ----------------------------------------------------------------------


def test_rate_100hz_holds_for_20_frames_from_the_past():
    """At 100 Hz on a 2 kHz grid the output is piecewise constant in runs of exactly 20 frames,
    holds a past input less than a period old, and the phase varies across windows."""
    sensor = SensorModel(rate_hz=100.0)
    assert sensor.period_frames(DT) == pytest.approx(20.0)
    b, w = 200, 200
    t = w + sensor.context_frames(DT)
    out = sense(sensor, _ramp(b, t, 2, 3), w, np.ones((2, 3)), DT, _rng(6))
    # every fingertip and channel is sampled at the same instants
    assert np.all(out == out[:, :, :1, :1])
    held = out[:, :, 0, 0].astype(np.int64)  # the frame whose input is held (input = frame index)
    np.testing.assert_array_equal(held, out[:, :, 0, 0])
    frame = np.arange(t - w, t)[None]
    age = frame - held
    assert age.min() >= 0  # never from the future
    assert age.max() <= 19  # never older than one period
    assert np.all(np.diff(held, axis=1) >= 0)
    for row in held:
        runs = _runs(row)
        assert runs.size >= 8
        np.testing.assert_array_equal(runs, 20)
    phases = held[:, 0] % 20
    assert np.all(held % 20 == phases[:, None])  # one phase per window
    assert np.unique(phases).size >= 15


def test_rate_60hz_runs_of_33_or_34_frames():
    """At 60 Hz (33.33 frames per sample) the hold runs last 33 or 34 frames, 33.33 on average,
    and always hold a past input."""
    sensor = SensorModel(rate_hz=60.0)
    b, w = 100, 600
    t = w + sensor.context_frames(DT)
    out = sense(sensor, _ramp(b, t), w, 1.0, DT, _rng(7))
    held = out[:, :, 0, 0].astype(np.int64)
    age = np.arange(t - w, t)[None] - held
    assert age.min() >= 0
    assert age.max() <= 33
    runs = np.concatenate([_runs(row) for row in held])
    assert set(np.unique(runs)) <= {33, 34}
    assert {33, 34} <= set(np.unique(runs))
    assert runs.mean() == pytest.approx(100 / 3, abs=0.1)
    assert np.unique(held[:, 0] % 33).size > 10  # phases differ across windows


# --- delay ---------------------------------------------------------------------------------------


def test_delay_shifts_by_round_delay_over_dt():
    """delay_s = 0.01 at dt 5e-4 reads the input 20 frames earlier."""
    sensor = SensorModel(delay_s=0.01)
    assert sensor.delay_frames(DT) == 20
    b, w = 5, 100
    t = w + 20
    seg = _rng(8).normal(size=(b, t, 2, 3))
    out = sense(sensor, seg, w, SCALE, DT, _rng())
    k = np.arange(w)
    np.testing.assert_array_equal(out, seg[:, t - w + k - 20].astype(np.float32))


@pytest.mark.parametrize(("delay_s", "frames"), [(0.0102, 20), (0.0103, 21), (0.0, 0), (3e-4, 1)])
def test_delay_frames_rounds(delay_s, frames):
    """delay_frames is delay_s / dt rounded to the nearest frame."""
    assert SensorModel(delay_s=delay_s).delay_frames(DT) == frames


def test_delay_without_context_holds_first_frame():
    """With no frames before the window the delayed reading before the first frame is frame 0."""
    seg = _rng(9).normal(size=(2, 50, 1, 2))
    out = sense(SensorModel(delay_s=0.01), seg, 50, 1.0, DT, _rng())
    src = np.maximum(np.arange(50) - 20, 0)
    np.testing.assert_array_equal(out, seg[:, src].astype(np.float32))


# --- drop ----------------------------------------------------------------------------------------


def test_drop_fraction_and_hold_of_previous_sample():
    """At full rate a fraction ~drop of frames is lost, and each lost frame holds the previous
    delivered (past) sample."""
    p, b, w = 0.3, 100, 500
    t = w + 200  # far more context than two dropped samples, so a delivered one precedes
    out = sense(SensorModel(drop=p), _ramp(b, t), w, 1.0, DT, _rng(10))
    held = out[:, :, 0, 0].astype(np.int64)
    frame = np.arange(t - w, t)[None] + np.zeros((b, 1), dtype=np.int64)
    lost = held != frame
    assert lost.mean() == pytest.approx(p, abs=0.01)
    assert np.all(held <= frame)
    # a lost frame repeats the one before it (the previous delivered sample)
    assert np.all(held[:, 1:][lost[:, 1:]] == held[:, :-1][lost[:, 1:]])
    # lost runs are geometric: P(next also lost | lost) = p
    both = (lost[:, 1:] & lost[:, :-1]).sum() / lost[:, :-1].sum()
    assert both == pytest.approx(p, abs=0.02)


def test_drop_with_rate_holds_whole_periods():
    """With rate and drop, hold runs last a whole number of periods and never read the future."""
    sensor = SensorModel(rate_hz=100.0, drop=0.4)
    b, w, t = 50, 400, 800
    out = sense(sensor, _ramp(b, t), w, 1.0, DT, _rng(11))
    held = out[:, :, 0, 0].astype(np.int64)
    assert np.all(held <= np.arange(t - w, t)[None])
    runs = np.concatenate([_runs(row) for row in held])
    np.testing.assert_array_equal(runs % 20, 0)
    assert np.any(runs > 20)


# --- context_frames ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("settings", "frames"),
    [
        ({}, 0),
        ({"delay_s": 0.01}, 20),
        ({"rate_hz": 100.0}, 40),
        ({"rate_hz": 60.0}, 68),
        ({"drop": 0.1}, 2),
        ({"delay_s": 0.01, "rate_hz": 100.0}, 60),
        ({"noise": 1.0, "gain": 1.0, "drift": 1.0, "bits": 8}, 0),
    ],
)
def test_context_frames_values(settings, frames):
    """context_frames is the delay plus two rounded-up sample periods when there is a hold."""
    assert SensorModel(**settings).context_frames(DT) == frames


@pytest.mark.parametrize(("rate_hz", "period"), [(100.0, 20), (60.0, 34)])
def test_context_frames_let_delay_and_hold_read_recorded_forces(rate_hz, period):
    """With W + context_frames the delayed, held output is the true shifted input (never the
    frame-0 clamp); without context the early frames are clamped."""
    sensor = SensorModel(delay_s=0.01, rate_hz=rate_hz)
    b, w = 200, 100
    t = w + sensor.context_frames(DT)
    out = sense(sensor, _ramp(b, t) + 1.0, w, 1.0, DT, _rng(12))
    read = out[:, :, 0, 0].astype(np.int64) - 1  # the input frame the output reports
    age = np.arange(t - w, t)[None] - 20 - read  # how long the delayed value has been held
    assert age.min() >= 0
    assert age.max() <= period - 1
    assert read.min() >= 1  # frame 0 is never read
    # the same sensor on a segment without context reads the clamped frame 0 (or a sample held
    # back to before the first instant) early on: not the true delayed, held input
    bare = sense(sensor, _ramp(b, w) + 1.0, w, 1.0, DT, _rng(12))
    read0 = bare[:, :, 0, 0].astype(np.int64) - 1
    assert np.mean(read0[:, :20] == 0) > 0.5
    assert np.any(np.arange(w)[None] - 20 - read0 < 0)


# --- reproducibility -----------------------------------------------------------------------------


def test_same_seed_same_output_different_seed_differs():
    """All draws come from the generator: the same seed repeats the output, another changes it,
    and the input is left untouched."""
    sensor = SensorModel(
        noise=0.1, gain=0.05, drift=0.2, bits=10, full_scale_n=50.0, rate_hz=60.0,
        delay_s=0.005, drop=0.1,
    )  # fmt: skip
    seg = _rng(13).normal(size=(4, 300, 2, 3)) * 5
    before = seg.copy()
    a = sense(sensor, seg, 150, SCALE, DT, _rng(42))
    b = sense(sensor, seg, 150, SCALE, DT, _rng(42))
    c = sense(sensor, seg, 150, SCALE, DT, _rng(43))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    np.testing.assert_array_equal(seg, before)


# --- validation ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "settings",
    [
        {"noise": -0.1},
        {"noise": float("nan")},
        {"gain": -0.01},
        {"drift": -1.0},
        {"delay_s": -0.001},
        {"drop": 1.0},
        {"drop": 1.5},
        {"drop": -0.1},
        {"bits": 0},
        {"bits": 33},
        {"full_scale_n": 0.0},
        {"rate_hz": 0.0},
        {"rate_hz": -60.0},
    ],
    ids=lambda s: f"{next(iter(s))}={next(iter(s.values()))}",
)
def test_out_of_range_settings_raise(settings):
    """An out-of-range setting raises SensorModelError (a ValueError) naming the field, both from
    the constructor and from from_config."""
    field = next(iter(settings))
    with pytest.raises(SensorModelError, match=field):
        SensorModel(**settings)
    with pytest.raises(ValueError, match=field):
        SensorModel.from_config(settings)


def test_from_config_refuses_unknown_keys_and_accepts_known():
    """from_config names unknown keys, treats None as the default, and coerces bits to int."""
    with pytest.raises(SensorModelError, match="bogus"):
        SensorModel.from_config({"noise": 0.1, "bogus": 1})
    assert SensorModel.from_config(None) == SensorModel()
    assert SensorModel.from_config({}) == SensorModel()
    s = SensorModel.from_config({"bits": 8.0, "rate_hz": 60})
    assert s.bits == 8 and isinstance(s.bits, int)
    assert s.rate_hz == 60


def test_with_strength_sets_one_field():
    """with_strength sets the named corruption's field, leaves the rest, and refuses bad input."""
    base = SensorModel(noise=0.1)
    s = base.with_strength("rate", 60)
    assert s.rate_hz == 60 and s.noise == 0.1
    assert base.rate_hz is None
    assert base.with_strength("quantisation", 8).bits == 8
    assert base.with_strength("delay", 0.01).delay_s == 0.01
    assert base.with_strength("noise", 0.0).is_identity
    with pytest.raises(SensorModelError, match="bogus"):
        base.with_strength("bogus", 1)
    with pytest.raises(SensorModelError, match="drop"):
        base.with_strength("drop", 1.0)


# --- input shape ---------------------------------------------------------------------------------


@pytest.mark.parametrize("sensor", [SensorModel(), SensorModel(noise=0.1)], ids=["id", "noisy"])
def test_segments_shorter_than_window_raise(sensor):
    """Segments shorter than the window, or not 4-D, raise SensorModelError."""
    with pytest.raises(SensorModelError, match="shape"):
        sense(sensor, np.zeros((2, 19, 2, 3)), 20, SCALE, DT, _rng())
    with pytest.raises(SensorModelError, match="shape"):
        sense(sensor, np.zeros((19, 2, 3)), 10, SCALE, DT, _rng())
    assert sense(sensor, np.zeros((2, 20, 2, 3)), 20, SCALE, DT, _rng()).shape == (2, 20, 2, 3)


@pytest.mark.parametrize("settings", [{"drop": 0.5}, {"rate_hz": 100.0, "drop": 0.5}])
def test_drops_never_report_the_future_even_with_tight_context(settings):
    """When every sample before a frame was lost, the oldest reading is held, not a later one."""
    sensor = SensorModel(**settings)
    b, w = 500, 100
    t = w + sensor.context_frames(DT)
    seg = np.broadcast_to(np.arange(t, dtype=np.float64)[None, :, None, None], (b, t, 5, 2))
    out = sense(sensor, seg, w, np.ones((5, 2)), DT, np.random.default_rng(3))
    assert (out[..., 0, 0] <= np.arange(t - w, t)[None]).all()
