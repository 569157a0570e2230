"""The load-ramp protocol: a slowly rising external force at the object's centre of mass.

Under the strict contact model a held object does not creep, and under gravity alone a grasp drops
at once or never moves. The ramp makes held grasps slip when the load exceeds their friction
capacity: after ``start_s`` (t0) the object carries, besides its weight, F(t) = m g k (t - t0) up to
``ceiling`` x m g, along a direction drawn per grasp from a configured set. The force goes into
``xfrc_applied`` of the object body through ``mujoco.rollout``'s control vector, so no Python runs
per step; it is recorded in the traces as channel ``load`` (not a model input).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

# The directions a grasp's load may take (simulation frame = hand frame, gravity rotated into it).
DIRECTION_SETS = ("gravity", "hand_axes", "gravity_axes", "sphere")
#: How the load grows: ``linear`` to the ceiling; ``hold``: as linear until the object first
#: slides (speed >= ``slip_speed``), then held at ``hold_fraction`` of the load it slid at;
#: ``servo``: as linear until the first slide, then servoed on the speed (falling at ``rate`` while
#: the object is faster than ``slip_speed``, rising at ``rate`` while slower), so a slipping
#: object keeps sliding near that speed, in contact, instead of being torn out of the grasp.
LOAD_PATHS = ("linear", "hold", "servo")
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
    axes (uniformly), gravity or one of the six axes (seven choices, uniformly), or uniform on
    the sphere."""
    g = np.asarray(gravity, dtype=np.float64)
    if kind == "gravity":
        return g / np.linalg.norm(g)
    if kind in ("hand_axes", "gravity_axes"):
        k = int(rng.integers(6 if kind == "hand_axes" else 7))
        if k == 6:
            return g / np.linalg.norm(g)
        axis = np.zeros(3)
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



@dataclass
class RampLoad:
    """One grasp's load: a fixed unit ``direction`` (simulation frame) and a magnitude that follows
    :func:`ramp_magnitude`; under path ``hold`` it stops rising once the object slides.

    The replay loop asks :meth:`chunk_steps` how far it may roll out before it must look at the
    object's speed again (``feedback_steps`` while a ``hold`` ramp is still rising, so the load
    overshoots the slip load by at most ``rate * weight * feedback_steps * dt``), takes
    :meth:`forces` for those steps and reports the speeds back through :meth:`observe`.
    """

    direction: np.ndarray
    weight: float  # m g [N]
    dt: float
    start_s: float
    rate: float
    ceiling: float
    path: str = "linear"
    slip_speed: float = 0.0012  # [m/s]
    hold_fraction: float = 1.0
    feedback_steps: int = 20
    # the magnitude [N] once the object has slid: held (path hold) or servoed (path servo, as at
    # the end of the last chunk)
    held: float | None = None
    slip_step: int | None = None  # the step it first slid at

    def __post_init__(self) -> None:
        if self.path not in LOAD_PATHS:
            raise ValueError(f"unknown load path {self.path!r}; valid: {', '.join(LOAD_PATHS)}")
        self.direction = np.asarray(self.direction, dtype=np.float64)

    def magnitudes(self, first: int, n: int) -> np.ndarray:
        """|F| [N] at steps ``first .. first + n - 1``."""
        if self.held is not None:
            return np.full(n, self.held)
        return ramp_magnitude(n, self.dt, self.start_s, self.rate, self.ceiling, self.weight, first)

    def forces(self, first: int, n: int) -> np.ndarray:
        """The force rows (n x 3) for steps ``first .. first + n - 1``."""
        return self.magnitudes(first, n)[:, None] * self.direction[None]

    def _rising(self, first: int, n: int) -> bool:
        if self.path == "servo":
            return True  # it needs the speed at every feedback step, before and after a slide
        return self.path == "hold" and self.held is None and (
            self.magnitudes(first, n)[-1] < self.ceiling * self.weight
        )  # fmt: skip

    def chunk_steps(self, first: int, default: int) -> int:
        """Steps the next rollout may take from ``first``: ``default``, or up to the ramp's start
        and then ``feedback_steps`` at a time while a ``hold`` ramp is rising."""
        if not self._rising(first, default):
            return default
        start = round(self.start_s / self.dt)
        if first < start:
            return min(default, start - first)
        return min(default, self.feedback_steps)

    def observe(self, first: int, speed: np.ndarray) -> None:
        """Take the object's speeds [m/s] at steps ``first ..``: a ``hold`` ramp freezes at
        ``hold_fraction`` of the load of the first loaded step at ``slip_speed`` or faster."""
        if self.path == "linear" or (self.path == "hold" and self.held is not None):
            return
        if self.held is not None:  # servo: one bang-bang step per chunk on its last speed
            step = self.rate * self.weight * len(speed) * self.dt
            up = speed[-1] < self.slip_speed
            self.held = float(np.clip(self.held + (step if up else -step), 0.0,
                                      self.ceiling * self.weight))  # fmt: skip
            return
        magnitude = self.magnitudes(first, len(speed))
        slid = np.flatnonzero((magnitude > 0) & (speed >= self.slip_speed))
        if len(slid):
            self.slip_step = first + int(slid[0])
            fraction = self.hold_fraction if self.path == "hold" else 1.0
            self.held = fraction * float(magnitude[slid[0]])


def ramp_load(ramp: dict, direction: np.ndarray, weight: float, dt: float) -> RampLoad:
    """The :class:`RampLoad` of one grasp from the ``replay.ramp`` config group."""
    return RampLoad(
        direction=direction, weight=weight, dt=dt, start_s=float(ramp["start_s"]),
        rate=float(ramp["rate"]), ceiling=float(ramp["ceiling"]), path=ramp["path"],
        slip_speed=float(ramp["slip_speed"]), hold_fraction=float(ramp["hold_fraction"]),
        feedback_steps=max(1, round(float(ramp["feedback_s"]) / dt)),
    )  # fmt: skip
