"""The load-ramp protocol: a slowly rising external force at the object's centre of mass.

Under the strict contact model a held object does not creep, and under gravity alone a grasp drops
at once or never moves. The ramp makes held grasps slip when the load exceeds their friction
capacity: after ``start_s`` (t0) the object carries, besides its weight, F(t) = m g k (t - t0) up to
``ceiling`` x m g, along a direction drawn per grasp from a configured set. The force goes into
``xfrc_applied`` of the object body through ``mujoco.rollout``'s control vector, so no Python runs
per step; it is recorded in the traces as channel ``load`` (not a model input).
"""

from __future__ import annotations

import mujoco
import numpy as np

# The directions a grasp's load may take (simulation frame = hand frame, gravity rotated into it).
DIRECTION_SETS = ("gravity", "hand_axes", "sphere")
#: rollout's control vector with the ramp: the actuator targets, then every body's 6-D wrench.
CONTROL_SPEC = mujoco.mjtState.mjSTATE_CTRL | mujoco.mjtState.mjSTATE_XFRC_APPLIED


def ramp_magnitude(
    steps: int, dt: float, start_s: float, rate: float, ceiling: float, weight: float,
    first_step: int = 0,
) -> np.ndarray:  # fmt: skip
    """|F| [N] at steps ``first_step .. first_step + steps - 1``: 0 before t0, then
    ``weight * rate * (t - t0)`` capped at ``ceiling * weight`` (``weight`` = m g [N])."""
    t = (first_step + np.arange(steps)) * dt
    return np.clip(weight * rate * (t - start_s), 0.0, ceiling * weight)


def ramp_direction(kind: str, gravity: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A unit load direction in the simulation frame: along ``gravity``, one of the six hand-frame
    axes (uniformly), or uniform on the sphere."""
    if kind == "gravity":
        g = np.asarray(gravity, dtype=np.float64)
        return g / np.linalg.norm(g)
    if kind == "hand_axes":
        axis = np.zeros(3)
        k = int(rng.integers(6))
        axis[k % 3] = 1.0 if k < 3 else -1.0
        return axis
    if kind == "sphere":
        v = rng.standard_normal(3)
        return v / np.linalg.norm(v)
    raise ValueError(f"unknown ramp direction set {kind!r}; valid: {', '.join(DIRECTION_SETS)}")


def control_rows(
    model: mujoco.MjModel, ctrl: np.ndarray, body: int, forces: np.ndarray
) -> np.ndarray:
    """rollout's control array (1, n, nu + 6 nbody) for :data:`CONTROL_SPEC`: constant actuator
    targets ``ctrl`` and, at every step, ``forces[i]`` (n x 3, simulation frame) on ``body``."""
    n = len(forces)
    width = mujoco.mj_stateSize(model, CONTROL_SPEC)
    rows = np.zeros((1, n, width))
    rows[0, :, : model.nu] = ctrl
    start = model.nu + 6 * body
    rows[0, :, start : start + 3] = forces
    return rows

