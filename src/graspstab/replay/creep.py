"""Creep of a statically held object under a contact model (3.2; docs/pipeline.md "Grasp replay").

MuJoCo's soft contacts let a held object slide slowly by design; whether that creep is far below
eq. 23's 1.2 mm/s or of its order decides what "unstable" means. Two measurements:

* :func:`box_creep`, the analytic case: a 0.2 kg box squeezed between two position-driven
  fingertip pads with a given force, under the contact model's solver options; mean |v_z| over
  the second half of the hold. Squeezed hard enough (5 N each side at friction 1 against 1.96 N
  of weight) it must stay, so any speed is creep; squeezed too weakly (0.3 N) it must fall.
* :func:`held_creep`, on a run's own replays: the median object speed over the final second of
  every replay still held at the end.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from graspstab.replay.scene import CONES

BOX_MASS = 0.2  # [kg]
HELD_SQUEEZE = 5.0  # [N] per side: 2 x 5 N x friction 1 = 10 N of friction against 1.96 N
WEAK_SQUEEZE = 0.3  # [N] per side: 0.6 N of friction cannot carry 1.96 N, so it must fall
BOX = """
<mujoco>
  <option timestep="{dt}" gravity="0 0 0"/>
  <worldbody>
    <body name="tip_a" pos="-0.035 0 0">
      <joint name="slide_a" type="slide" axis="1 0 0" damping="5"/>
      <geom type="box" size="0.01 0.015 0.015" mass="0.05"/>
    </body>
    <body name="tip_b" pos="0.035 0 0">
      <joint name="slide_b" type="slide" axis="-1 0 0" damping="5"/>
      <geom type="box" size="0.01 0.015 0.015" mass="0.05"/>
    </body>
    <body name="object"><freejoint/><geom type="box" size="0.02 0.02 0.02" mass="{mass}"/></body>
  </worldbody>
  <actuator>
    <position joint="slide_a" kp="1000"/><position joint="slide_b" kp="1000"/>
  </actuator>
</mujoco>
"""


def squeezed_box(
    contact: dict[str, Any], squeeze: float = HELD_SQUEEZE, dt: float = 0.0005
) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The box between its two pads, each pressing with ``squeeze`` [N], under the solver options
    of ``contact``: settled for 0.2 s without gravity, then gravity switched on (not yet
    stepped). The analytic case for creep and for the load ramp."""
    spec = mujoco.MjSpec.from_string(BOX.format(dt=dt, mass=BOX_MASS))
    spec.option.cone = CONES[contact["cone"]]
    spec.option.impratio = float(contact["impratio"])
    spec.option.noslip_iterations = int(contact["noslip_iterations"])
    model = spec.compile()
    data = mujoco.MjData(model)
    model.actuator_forcerange[:] = (-squeeze, squeeze)
    model.actuator_forcelimited[:] = 1
    data.ctrl[:] = 0.05  # targets past the box faces: each pad presses with its force limit
    for _ in range(round(0.2 / dt)):
        mujoco.mj_step(model, data)
    model.opt.gravity[:] = (0.0, 0.0, -9.81)
    return model, data


def box_creep(
    contact: dict[str, Any], squeeze: float = HELD_SQUEEZE, seconds: float = 4.0,
    dt: float = 0.0005,
) -> float:  # fmt: skip
    """Mean |v_z| [m/s] of the squeezed box over the second half of ``seconds`` under gravity,
    with the solver options (cone, impratio, noslip iterations) of ``contact``."""
    model, data = squeezed_box(contact, squeeze, dt)
    n = round(seconds / dt)
    vz = np.empty(n)
    dof = model.jnt_dofadr[model.body("object").jntadr[0]]
    for i in range(n):
        mujoco.mj_step(model, data)
        vz[i] = data.qvel[dof + 2]
    return float(np.abs(vz[n // 2 :]).mean())


def held_creep(velocity: np.ndarray, dt: float, last_s: float = 1.0) -> float:
    """Median object speed [m/s] over the final ``last_s`` of one replay's velocity trace."""
    v = np.asarray(velocity, dtype=np.float64)[-max(1, round(last_s / dt)) :]
    return float(np.median(np.linalg.norm(v, axis=1))) if len(v) else float("nan")
