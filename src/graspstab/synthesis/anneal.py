"""Simulated annealing of the grasp energy (thesis 3.1.4), vectorised over many chains at once.

Every chain draws its proposals and acceptance tests from its own random stream (one numpy
``SeedSequence`` per grasp), in blocks of a fixed length, so a chain's trajectory depends only on
its seed and start: not on how many chains share a call, nor on the thread count (up to
floating-point noise in the energy).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import torch

log = logging.getLogger(__name__)

#: Proposal dimensions: wrist position (3), 6-D rotation (6), finger joints (16).
N_POS, N_ROT, N_JOINTS = 3, 6, 16
N_DIMS = N_POS + N_ROT + N_JOINTS
#: Iterations drawn per refill of a chain's noise; a constant, so streams never depend on batching.
NOISE_BLOCK = 200

EnergyFn = Callable[[torch.Tensor, torch.Tensor, torch.Tensor], torch.Tensor]


@dataclass(frozen=True)
class AnnealSchedule:
    """Proposal scales and the exponential temperature schedule (3.1.4)."""

    iterations: int = 6000  # 3.1.4
    temperature_start: float = 1000.0  # 3.1.4: T decays exponentially from 1000 ...
    temperature_end: float = 1.0  # ... to 1
    step_position: float = 0.005  # sigma [m], 3.1.4
    step_rotation: float = 0.02  # sigma of the 6-D rotation, 3.1.4
    step_joints: float = 0.05  # sigma [rad], 3.1.4

    @classmethod
    def from_params(cls, params: dict) -> AnnealSchedule:
        """The schedule from the ``synthesis.annealing`` config slice (extra keys ignored)."""
        return cls(**{k: params[k] for k in cls.__dataclass_fields__})

    def temperature(self, iteration: int) -> float:
        """T at ``iteration`` (0-based): T_start at the first, T_end at the last."""
        if self.iterations <= 1:
            return self.temperature_end
        frac = iteration / (self.iterations - 1)
        return self.temperature_start * (self.temperature_end / self.temperature_start) ** frac

    def steps(self) -> np.ndarray:
        """Per-dimension proposal standard deviations, (25,)."""
        return np.concatenate(
            [
                np.full(N_POS, self.step_position),
                np.full(N_ROT, self.step_rotation),
                np.full(N_JOINTS, self.step_joints),
            ]
        )


class ChainNoise:
    """Independent Gaussian proposals and acceptance uniforms, one stream per chain."""

    def __init__(self, seeds: Sequence[np.random.SeedSequence]) -> None:
        self._gens = [np.random.Generator(np.random.PCG64(s)) for s in seeds]
        self._normals = np.empty((0, len(seeds), N_DIMS))
        self._uniforms = np.empty((0, len(seeds)))
        self._cursor = 0

    def _refill(self) -> None:
        normals = np.empty((NOISE_BLOCK, len(self._gens), N_DIMS))
        uniforms = np.empty((NOISE_BLOCK, len(self._gens)))
        for i, gen in enumerate(self._gens):
            normals[:, i] = gen.standard_normal((NOISE_BLOCK, N_DIMS))
            uniforms[:, i] = gen.random(NOISE_BLOCK)
        self._normals, self._uniforms, self._cursor = normals, uniforms, 0

    def next(self) -> tuple[np.ndarray, np.ndarray]:
        """The next iteration's (normals (B, 25), uniforms (B,))."""
        if self._cursor == len(self._normals):
            self._refill()
        k = self._cursor
        self._cursor += 1
        return self._normals[k], self._uniforms[k]


@dataclass
class AnnealResult:
    """Best state along each chain's trajectory and its bookkeeping (numpy, float64)."""

    wrist_pos: np.ndarray  # (B, 3)
    rot6d: np.ndarray  # (B, 6)
    joints: np.ndarray  # (B, 16)
    energy: np.ndarray  # (B,) total energy at the best state
    energy_start: np.ndarray  # (B,) total energy at the start
    acceptance_rate: np.ndarray  # (B,) accepted proposals / iterations
    best_iteration: np.ndarray  # (B,) iteration at which the best state was found (-1: start)


def anneal(
    energy_fn: EnergyFn,
    wrist_pos: np.ndarray,
    rot6d: np.ndarray,
    joints: np.ndarray,
    joint_lower: np.ndarray,
    joint_upper: np.ndarray,
    schedule: AnnealSchedule,
    seeds: Sequence[np.random.SeedSequence],
    dtype: torch.dtype = torch.float32,
    progress: Callable[[int, int], None] | None = None,
) -> AnnealResult:
    """Anneal B chains from their starts; keep the best state each chain visits (3.1.4).

    Each step adds independent Gaussian noise to every coordinate, clips the joints to their
    limits, accepts if the energy falls and otherwise with probability exp(-dE/T), with T
    decaying exponentially over the iterations. ``energy_fn(pos, rot6d, joints) -> (B,)``.
    """
    n = len(seeds)
    for name, arr, width in (
        ("wrist_pos", wrist_pos, 3),
        ("rot6d", rot6d, 6),
        ("joints", joints, 16),
    ):
        if np.shape(arr) != (n, width):
            raise ValueError(f"{name} must have shape ({n}, {width}), got {np.shape(arr)}")
    lower = torch.as_tensor(joint_lower, dtype=dtype)
    upper = torch.as_tensor(joint_upper, dtype=dtype)
    state = torch.cat(
        [
            torch.as_tensor(wrist_pos, dtype=dtype),
            torch.as_tensor(rot6d, dtype=dtype),
            torch.clamp(torch.as_tensor(joints, dtype=dtype), lower, upper),
        ],
        dim=1,
    )
    steps = torch.as_tensor(schedule.steps(), dtype=dtype)
    noise = ChainNoise(seeds)

    def evaluate(x: torch.Tensor) -> torch.Tensor:
        return energy_fn(x[:, :N_POS], x[:, N_POS : N_POS + N_ROT], x[:, N_POS + N_ROT :])

    with torch.no_grad():
        energy = evaluate(state)
        energy_start = energy.clone()
        best_state, best_energy = state.clone(), energy.clone()
        best_iter = torch.full((n,), -1, dtype=torch.int64)
        accepted = torch.zeros(n, dtype=torch.int64)
        t0 = time.perf_counter()
        for it in range(schedule.iterations):
            normals, uniforms = noise.next()
            proposal = state + torch.as_tensor(normals, dtype=dtype) * steps
            proposal[:, N_POS + N_ROT :] = torch.clamp(proposal[:, N_POS + N_ROT :], lower, upper)
            new_energy = evaluate(proposal)
            delta = (new_energy - energy).to(torch.float64)
            temperature = schedule.temperature(it)
            # accept a fall outright; a rise with Boltzmann probability exp(-dE/T), eq. 15
            accept = (delta <= 0) | (
                torch.as_tensor(uniforms) < torch.exp(-delta.clamp(min=0) / temperature)
            )
            accept &= torch.isfinite(new_energy)
            state = torch.where(accept[:, None], proposal, state)
            energy = torch.where(accept, new_energy, energy)
            accepted += accept.to(torch.int64)
            better = energy < best_energy
            best_state = torch.where(better[:, None], state, best_state)
            best_energy = torch.where(better, energy, best_energy)
            best_iter = torch.where(better, torch.full_like(best_iter, it), best_iter)
            if progress is not None:
                progress(it + 1, schedule.iterations)
        elapsed = time.perf_counter() - t0
    log.debug("annealed %d chains x %d iterations in %.1f s", n, schedule.iterations, elapsed)
    best = best_state.to(torch.float64).numpy()
    return AnnealResult(
        wrist_pos=best[:, :N_POS],
        rot6d=best[:, N_POS : N_POS + N_ROT],
        joints=best[:, N_POS + N_ROT :],
        energy=best_energy.to(torch.float64).numpy(),
        energy_start=energy_start.to(torch.float64).numpy(),
        acceptance_rate=accepted.numpy() / max(schedule.iterations, 1),
        best_iteration=best_iter.numpy(),
    )


def log_progress(label: str, every_s: float = 10.0) -> Callable[[int, int], None]:
    """A progress callback that logs ``label: i/n iterations`` at most every ``every_s`` seconds."""
    state = {"last": -math.inf, "t0": time.perf_counter()}

    def report(done: int, total: int) -> None:
        now = time.perf_counter()
        if now - state["last"] >= every_s or done == total:
            state["last"] = now
            rate = done / max(now - state["t0"], 1e-9)
            log.info("%s: %d/%d iterations (%.0f it/s)", label, done, total, rate)

    return report
