"""Tests of the simulated annealer on analytic energies (3.1.4): schedule, acceptance, seeds."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from graspstab.synthesis.anneal import AnnealSchedule, ChainNoise, anneal

LOWER = np.full(16, -0.5)
UPPER = np.full(16, 1.0)
TARGET = np.concatenate([[0.01, -0.02, 0.03], [1, 0, 0, 0, 1, 0], np.full(16, 0.2)])


def bowl(pos: torch.Tensor, r6: torch.Tensor, joints: torch.Tensor) -> torch.Tensor:
    """A quadratic bowl with its minimum (0) at TARGET."""
    x = torch.cat([pos, r6, joints], dim=1)
    return 1e4 * ((x - torch.as_tensor(TARGET, dtype=x.dtype)) ** 2).sum(dim=1)


def _seeds(n: int, offset: int = 0) -> list[np.random.SeedSequence]:
    return np.random.SeedSequence(7).spawn(n + offset)[offset:]


def _starts(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(1)
    return rng.normal(0, 0.05, (n, 3)), rng.normal(0, 1, (n, 6)), rng.uniform(-0.4, 0.9, (n, 16))


def test_schedule_is_exponential_from_start_to_end() -> None:
    s = AnnealSchedule(iterations=6000, temperature_start=1000.0, temperature_end=1.0)
    assert s.temperature(0) == pytest.approx(1000.0)
    assert s.temperature(5999) == pytest.approx(1.0)
    # exponential: equal ratios over equal spans; the midpoint is the geometric mean
    assert s.temperature(2999.5) == pytest.approx(np.sqrt(1000.0))
    ratios = [s.temperature(i + 100) / s.temperature(i) for i in (0, 1000, 4000)]
    assert np.allclose(ratios, ratios[0])
    assert s.steps().tolist() == [0.005] * 3 + [0.02] * 6 + [0.05] * 16


def test_chain_noise_depends_only_on_the_chain_seed() -> None:
    seeds = _seeds(5)
    together = ChainNoise(seeds)
    alone = ChainNoise(seeds[3:4])
    for _ in range(450):  # crosses block boundaries
        n_all, u_all = together.next()
        n_one, u_one = alone.next()
        assert np.array_equal(n_all[3], n_one[0]) and u_all[3] == u_one[0]


def test_annealing_descends_a_bowl_and_keeps_the_best() -> None:
    n = 8
    pos, r6, q = _starts(n)
    sched = AnnealSchedule(iterations=1500, temperature_start=10.0, temperature_end=1e-3)
    res = anneal(bowl, pos, r6, q, LOWER, UPPER, sched, _seeds(n), dtype=torch.float64)
    assert np.all(res.energy <= res.energy_start)
    assert np.median(res.energy) < 0.05 * np.median(res.energy_start)
    # the reported energy is the energy of the reported state
    again = bowl(*(torch.as_tensor(a) for a in (res.wrist_pos, res.rot6d, res.joints)))
    assert np.allclose(again.numpy(), res.energy)
    assert np.all((res.joints >= LOWER) & (res.joints <= UPPER))
    assert np.all((res.acceptance_rate > 0) & (res.acceptance_rate < 1))


def test_joints_are_clipped_before_evaluation() -> None:
    seen: list[torch.Tensor] = []

    def spy(pos: torch.Tensor, r6: torch.Tensor, joints: torch.Tensor) -> torch.Tensor:
        seen.append(joints.clone())
        return torch.zeros(len(pos), dtype=pos.dtype)

    pos, r6, q = _starts(4)
    q[:, 0] = 5.0  # outside the limits at the start
    anneal(spy, pos, r6, q, LOWER, UPPER, AnnealSchedule(iterations=50), _seeds(4))
    stacked = torch.stack(seen)
    assert torch.all(stacked >= torch.as_tensor(LOWER, dtype=stacked.dtype) - 1e-7)
    assert torch.all(stacked <= torch.as_tensor(UPPER, dtype=stacked.dtype) + 1e-7)


def test_boltzmann_acceptance_matches_the_analytic_rate() -> None:
    # E = w * x: a step dx ~ N(0, s^2) changes E by w dx; at constant T the acceptance
    # probability is E[min(1, exp(-w dx / T))], computed here by quadrature.
    w, temp, s = 200.0, 1.0, 0.005

    def slope(pos: torch.Tensor, r6: torch.Tensor, joints: torch.Tensor) -> torch.Tensor:
        return w * pos[:, 0]

    z = np.linspace(-8, 8, 20001)
    pdf = np.exp(-0.5 * z**2) / np.sqrt(2 * np.pi)
    expected = np.trapezoid(pdf * np.minimum(1.0, np.exp(-w * s * z / temp)), z)
    n = 64
    pos, r6, q = _starts(n)
    sched = AnnealSchedule(iterations=400, temperature_start=temp, temperature_end=temp)
    res = anneal(slope, pos, r6, q, LOWER, UPPER, sched, _seeds(n), dtype=torch.float64)
    assert res.acceptance_rate.mean() == pytest.approx(expected, abs=0.01)
    assert expected < 0.8  # the test distinguishes Boltzmann acceptance from "always accept"


def test_results_do_not_depend_on_batching_or_threads() -> None:
    n = 6
    pos, r6, q = _starts(n)
    sched = AnnealSchedule(iterations=300, temperature_start=5.0, temperature_end=0.01)
    seeds = _seeds(n)
    whole = anneal(bowl, pos, r6, q, LOWER, UPPER, sched, seeds)
    threads = torch.get_num_threads()
    try:
        torch.set_num_threads(1)
        parts = [
            anneal(bowl, pos[a:b], r6[a:b], q[a:b], LOWER, UPPER, sched, seeds[a:b])
            for a, b in ((0, 2), (2, 5), (5, 6))
        ]
    finally:
        torch.set_num_threads(threads)
    joined = np.concatenate([p.joints for p in parts])
    assert np.allclose(joined, whole.joints, atol=1e-5)
    assert np.allclose(np.concatenate([p.energy for p in parts]), whole.energy, rtol=1e-5)


def test_bad_shapes_are_rejected() -> None:
    pos, r6, q = _starts(3)
    with pytest.raises(ValueError, match="joints must have shape"):
        anneal(bowl, pos, r6, q[:, :15], LOWER, UPPER, AnnealSchedule(iterations=2), _seeds(3))
