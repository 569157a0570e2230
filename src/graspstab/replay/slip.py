"""Contact slip at the hand's links: how fast the object slides over each fingertip and over the
links no sensor sees, the failure anatomy's first question (which contact gave way).

MuJoCo's sensors report contact forces, not the relative speed at a contact, so the replay samples
it from the rolled-out states every ``every`` steps (holding each sample until the next): the
state's kinematics and collision are recomputed on a scratch ``MjData`` (no dynamics, ~50 us a
sample), and each hand-object contact's relative velocity at its point, less its normal part, is
the slip speed. A soft contact slides a little whenever it carries tangential load (MuJoCo's
creep), so "slip" is a speed, and the labels and the anatomy choose their thresholds.
"""

from __future__ import annotations

import copy

import mujoco
import numpy as np

from graspstab.replay.sensors import SensorLayout

#: steps between two samples when the caller gives no sampler (10 ms at 0.5 ms steps)
DEFAULT_EVERY = 20


def body_classes(model: mujoco.MjModel, layout: SensorLayout) -> np.ndarray:
    """Per body: its fingertip's column (0 .. 4), ``len(fingertips)`` for another hand link, -1
    for a body outside the hand (the object, the world)."""
    cls = np.full(model.nbody, -1, dtype=np.int64)
    cls[list(layout.hand_bodies)] = len(layout.tip_bodies)
    for i, body in enumerate(layout.tip_bodies):
        cls[body] = i
    return cls


def point_velocity(data: mujoco.MjData, model: mujoco.MjModel, bodies: np.ndarray,
                   points: np.ndarray) -> np.ndarray:  # fmt: skip
    """World-frame linear velocity of the material points ``points (n, 3)`` of ``bodies (n,)``,
    from ``cvel`` (spatial velocity at the root's subtree centre of mass)."""
    root = model.body_rootid[bodies]
    w, v = data.cvel[bodies, :3], data.cvel[bodies, 3:]
    r = points - data.subtree_com[root]
    # w x r written out: np.cross costs ~50 us on a few rows, more than the collision pass
    return v + np.stack([w[:, 1] * r[:, 2] - w[:, 2] * r[:, 1],
                         w[:, 2] * r[:, 0] - w[:, 0] * r[:, 2],
                         w[:, 0] * r[:, 1] - w[:, 1] * r[:, 0]], axis=1)  # fmt: skip


def contact_slip(
    model: mujoco.MjModel, data: mujoco.MjData, object_body: int, classes: np.ndarray
) -> np.ndarray:
    """The largest slip speed [m/s] of the object's contacts per column of :func:`body_classes`
    (0 where a column has no contact), for ``data`` whose contacts and ``cvel`` are current."""
    out = np.zeros(int(classes.max(initial=-1)) + 1)
    n = data.ncon
    if n == 0 or not len(out):
        return out
    con = data.contact
    body = model.geom_bodyid[con.geom[:n]]  # (n, 2)
    hand = np.where(body[:, 0] == object_body, body[:, 1], body[:, 0])
    keep = (body == object_body).any(axis=1) & (classes[hand] >= 0)
    if not keep.any():
        return out
    body, p, normal = body[keep], con.pos[:n][keep], con.frame[:n, :3][keep]
    rel = point_velocity(data, model, body[:, 1], p) - point_velocity(data, model, body[:, 0], p)
    tangential = rel - (rel * normal).sum(axis=1, keepdims=True) * normal
    speed, cls = np.linalg.norm(tangential, axis=1), classes[hand[keep]]
    for c in np.unique(cls):
        out[c] = speed[cls == c].max()
    return out


def object_contacts_only(model: mujoco.MjModel, layout: SensorLayout) -> mujoco.MjModel:
    """A copy of ``model`` whose hand geoms collide with the object's and nothing else: the
    slip sampler's collision pass then skips the hand's self-contacts (about half its time)."""
    out = copy.copy(model)
    hand = np.isin(out.geom_bodyid, list(layout.hand_bodies))
    obj = out.geom_bodyid == layout.object_body
    out.geom_contype[:] = np.where(hand, 1, 0)
    out.geom_conaffinity[:] = np.where(obj, 1, 0)
    out.geom_contype[obj] = 0
    return out


class SlipSampler:
    """Slip columns for consecutive trace rows, sampled every ``every`` steps from the states a
    rollout produced and held in between (row t: the state before step t, as the sensors)."""

    SPEC = mujoco.mjtState.mjSTATE_FULLPHYSICS

    def __init__(self, model: mujoco.MjModel, layout: SensorLayout, every: int) -> None:
        if every < 1:
            raise ValueError(f"the slip sampling interval must be >= 1 step, got {every}")
        self.model, self.every = object_contacts_only(model, layout), int(every)
        self.scratch = mujoco.MjData(self.model)
        self.classes = body_classes(model, layout)
        self.object_body = layout.object_body
        self.last = np.zeros(len(layout.tip_bodies) + 1)

    def reset(self) -> None:
        """Forget the last sample: a new replay starts (the derived model is kept)."""
        self.last = np.zeros_like(self.last)

    def sample(self, state: np.ndarray) -> np.ndarray:
        """The slip columns of one full-physics state."""
        m, d = self.model, self.scratch
        if not np.isfinite(state).all():  # a diverging replay: its rows are cut anyway
            return self.last
        mujoco.mj_setState(m, d, state, self.SPEC)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_collision(m, d)
        mujoco.mj_comVel(m, d)
        return contact_slip(m, d, self.object_body, self.classes)

    def rows(self, first: int, initial: np.ndarray, states: np.ndarray) -> np.ndarray:
        """(n, columns) for rows ``first .. first + n - 1``: ``initial`` is the state before row
        ``first``, ``states (n, nstate)`` the states after each row's step."""
        n = len(states)
        out = np.empty((n, len(self.last)))
        at = np.flatnonzero((first + np.arange(n)) % self.every == 0)
        prev = 0
        for i in at:
            out[prev:i] = self.last
            self.last = self.sample(initial if i == 0 else states[i - 1])
            prev = i
        out[prev:] = self.last
        return out
