"""Run one replay in chunks of ``mujoco.rollout``; stop early once it can tell nothing more (3.2).

The physics runs in C: each chunk is one rollout call whose sensordata rows become trace rows
(:mod:`graspstab.replay.sensors`); between chunks Python only checks the stop rules. The solver's
warm start is carried across chunks, so chunking changes nothing but where a replay may stop.

Stop rules: ``contact_lost`` once no hand-object contact has existed for ``stop_after_loss_s``
(longer than the labelling stage's 0.1 s contact-end rule, 3.3.1, so no label can change);
``too_deep`` once the hand has been deeper than the depth rule's bound for its whole duration,
entirely after the settle search (so 3.3.1's depth rule rejects the grasp whatever its settle
index: :class:`DeepStop`); ``diverged`` on a non-finite state or a MuJoCo warning (such replays
are flagged and excluded); ``completed`` after all steps.

A :class:`Controller` (the closed loop's grip reflex) may read the fingertip forces between chunks
and move the actuator targets: it sets how long each chunk may be, supplies every step's targets
and sees each chunk's forces as soon as the chunk is simulated, as a controller on the hand would.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Protocol

import mujoco
import mujoco.rollout
import numpy as np

from graspstab.common.runs import earliest_run
from graspstab.replay.ramp import CONTROL_SPEC, RampLoad, control_rows
from graspstab.replay.sensors import SensorLayout, force_features, motion_features
from graspstab.replay.slip import DEFAULT_EVERY, SlipSampler
from graspstab.replay.traces import ANATOMY, CHANNELS, LOAD

# Rows of raw sensordata whose force channels are computed in one call: under the load ramp's
# feedback a chunk is 20 steps, and per-chunk numpy overhead would rival the physics.
FORCE_BATCH_ROWS = 2000


@dataclass(frozen=True)
class DeepStop:
    """The ``too_deep`` stop rule, in steps: d_t below ``depth`` [m] on ``run`` consecutive rows,
    all at or after row ``after``. With 3.3.1's bound and duration and ``after`` at the end of its
    settle search, every such replay is one the labelling stage rejects (the settle index never
    lies later), so stopping it changes no window."""

    depth: float
    run: int
    after: int

    def step(self, carry: int, first_row: int, dist: np.ndarray) -> tuple[bool, int]:
        """Whether a qualifying run has completed within these rows (``first_row`` onwards, the
        run reaching their start being ``carry`` rows long), and the run that reaches their end."""
        with np.errstate(invalid="ignore"):  # NaN (no contact) is never deep, as in 3.3.1
            deep = (np.asarray(dist) < self.depth) & (
                first_row + np.arange(len(dist)) >= self.after
            )
        seq = np.concatenate([np.ones(carry, dtype=bool), deep])
        hit = earliest_run(seq, self.run, len(seq)) is not None
        tail = len(seq) if seq.all() else len(seq) - 1 - int(np.flatnonzero(~seq)[-1])
        return hit, min(tail, self.run)


class Controller(Protocol):
    """What the replay needs of a controller in the loop (``graspstab.closedloop``)."""

    def chunk_steps(self, first: int, default: int) -> int:
        """Steps the next rollout may take from step ``first`` (at most ``default``) before the
        controller must see the forces again."""
        ...

    def targets(self, first: int, n: int, ctrl: np.ndarray) -> np.ndarray:
        """Actuator targets (n, nu) for steps ``first .. first + n - 1`` given the open-loop
        targets ``ctrl`` (nu,)."""
        ...

    def observe(self, first: int, normal: np.ndarray, shear: np.ndarray) -> None:
        """Take the fingertip forces (n, 5) [N] that steps ``first ..`` recorded."""
        ...

    def skip_to(self, step: int) -> None:
        """Start at step ``step`` (a replay continued from a fork): nothing acted before it."""
        ...


#: trace channel of a controlled replay: how far the targets were moved in, per step [rad]
REFLEX = "reflex"


@dataclass(frozen=True)
class Fork:
    """Where a replay can be continued from: the state at the start of one of its chunks and
    what the loop carried there (the solver's warm start, the stop rules' runs, the load's own
    state). A replay continued from it with the same controls computes the same rows as the
    original from there on (rollout chunking changes nothing), so a closed-loop run whose reflex
    first acts at step s need only simulate from the last fork at or before s."""

    step: int
    state: np.ndarray
    warmstart: np.ndarray
    lost_run: int
    deep_run: int
    load: RampLoad | None


@dataclass
class ReplayResult:
    """Trace rows (float32) and how the replay ended."""

    traces: dict[str, np.ndarray]  # CHANNELS, (T, ...) each
    steps: int  # steps simulated
    stop_reason: str  # completed | contact_lost | too_deep | diverged
    overflow: int  # most fingertip contacts that did not fit the sensor slots
    warnings: dict[str, int] = field(default_factory=dict)


def _warnings(data: mujoco.MjData) -> dict[str, int]:
    return {
        mujoco.mjtWarning(i).name: int(w.number)
        for i, w in enumerate(data.warning)
        if w.number > 0
    }


def run_replay(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    layout: SensorLayout,
    steps: int,
    chunk: int,
    stop_after_loss_steps: int,
    load: RampLoad | None = None,
    load_body: int = -1,
    deep_stop: DeepStop | None = None,
    controller: Controller | None = None,
    slip: SlipSampler | None = None,
    forks: dict[int, Fork] | None = None,
    start: Fork | None = None,
    prefix: dict[str, np.ndarray] | None = None,
) -> ReplayResult:
    """Roll out ``steps`` steps from ``data``'s current state with its current controls.

    ``data`` must be placed (positions, controls, gravity) by the caller; it ends in the last
    state. Row t of a trace is the sensor reading that step t computed, i.e. of the state before
    integration (MuJoCo evaluates sensors inside ``mj_step``). ``load`` is the load-ramp
    protocol's external force on body ``load_body`` (:mod:`graspstab.replay.ramp`; it sets the
    chunk lengths while it needs the object's speed), recorded as trace channel ``load``
    (simulation frame, the force during step t). ``deep_stop`` (None: never) stops a replay
    the depth rule will reject. ``controller`` (None: open loop) closes the loop: its targets
    drive the actuators and it sees every chunk's forces before the next chunk runs; the
    largest target offset it applies at each step is trace channel ``reflex``. ``slip`` samples
    the contact slip channels (:mod:`graspstab.replay.slip`; None: a new sampler every
    ``slip.DEFAULT_EVERY`` steps); build one per scene and pass it to every replay of the scene,
    since building one copies the model. ``forks`` (a dict) receives a :class:`Fork` at the
    start of every chunk; ``start`` continues a replay from one, ``prefix`` being the traces of
    the replay it was taken from (their rows before the fork are this replay's; the controller,
    if any, must be a fixed schedule that acts at or after the fork).
    """
    if chunk < 1 or steps < 1:
        raise ValueError(f"need steps >= 1 and chunk >= 1, got {steps}, {chunk}")
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(model, spec))
    control, control_spec = data.ctrl.copy()[None, None], mujoco.mjtState.mjSTATE_CTRL
    if load is not None and load_body < 0:
        raise ValueError(f"a load needs the body it acts on, got body {load_body}")
    channels = (*CHANNELS, *ANATOMY) if load is None else (*CHANNELS, *ANATOMY, LOAD)
    slip = SlipSampler(model, layout, DEFAULT_EVERY) if slip is None else slip
    slip.reset()
    if controller is not None:
        channels = (*channels, REFLEX)
    base = data.ctrl.copy()
    parts: dict[str, list[np.ndarray]] = {c: [] for c in channels}
    done, reason, overflow, lost_run, deep_run = 0, "completed", 0, 0, 0
    pending: list[np.ndarray] = []  # raw rows whose force channels are not computed yet
    pending_rows = 0
    if start is not None:
        if prefix is None:
            raise ValueError("a replay continued from a fork needs the traces it forked from")
        done, lost_run, deep_run = start.step, start.lost_run, start.deep_run
        mujoco.mj_setState(model, data, start.state, spec)
        data.qacc_warmstart[:] = start.warmstart
        load = copy.deepcopy(start.load) if load is not None else None
        for c in parts:
            parts[c].append(np.zeros(done, np.float32) if c == REFLEX
                            else np.asarray(prefix[c][:done], np.float32))  # fmt: skip
        if done > 0:  # the held slip sample of the row before the fork
            slip.last = np.r_[prefix["tip_slip"][done - 1], prefix["link_slip"][done - 1]]
        if controller is not None:
            controller.skip_to(done)

    def flush() -> int:
        nonlocal pending_rows
        if not pending:
            return 0
        forces = force_features(np.concatenate(pending), layout)
        pending.clear()
        pending_rows = 0
        for c, v in forces.items():
            if c in parts:
                parts[c].append(v.astype(np.float32))
        return int(forces["overflow"].max(initial=0))

    while done < steps:
        n = min(chunk, steps - done)
        mujoco.mj_getState(model, data, state, spec)
        if forks is not None:
            forks[done] = Fork(done, state.copy(), data.qacc_warmstart.copy(), lost_run,
                               deep_run, copy.deepcopy(load))  # fmt: skip
        if load is not None:
            n = load.chunk_steps(done, n)
        if controller is not None:
            n = max(1, controller.chunk_steps(done, n))
            targets = controller.targets(done, n, base)
            control = targets[None]
        if load is not None:
            forces = load.forces(done, n)
            control_spec = CONTROL_SPEC
            control = control_rows(model, targets if controller is not None else data.ctrl,
                                   load_body, forces)  # fmt: skip
        states, sensordata = mujoco.rollout.rollout(
            model,
            data,
            state[None],
            control,
            control_spec=int(control_spec),
            nstep=n,
            initial_warmstart=data.qacc_warmstart.copy()[None],
        )
        rows = motion_features(sensordata[0], layout)
        slips = slip.rows(done, state, states[0])
        rows["tip_slip"], rows["link_slip"] = slips[:, :-1], slips[:, -1]
        if load is not None:
            rows[LOAD] = forces
            load.observe(done, np.linalg.norm(rows["velocity"], axis=1))
        if controller is not None:
            rows[REFLEX] = np.max(targets - base[None], axis=1, initial=0.0)
        finite = np.isfinite(sensordata[0]).all(axis=1)
        ok = int(np.argmin(finite)) if not finite.all() else n
        for c in rows:
            parts[c].append(rows[c][:ok].astype(np.float32))
        if controller is not None:  # the controller reads this chunk's forces now
            now = force_features(sensordata[0][:ok], layout)
            for c, v in now.items():
                if c in parts:
                    parts[c].append(v.astype(np.float32))
            overflow = max(overflow, int(now["overflow"].max(initial=0)))
            controller.observe(done, now["normal"], now["shear"])
        else:
            pending.append(np.array(sensordata[0][:ok]))
            pending_rows += ok
        if pending_rows >= FORCE_BATCH_ROWS:
            overflow = max(overflow, flush())
        done += ok
        if ok < n or not np.isfinite(data.qpos).all() or _warnings(data):
            reason = "diverged"
            break
        # contact loss: the run of undefined d_t that reaches the end of this chunk
        defined = np.isfinite(rows["min_distance"])
        tail = n if not defined.any() else n - 1 - int(np.flatnonzero(defined)[-1])
        lost_run = lost_run + n if tail == n else tail
        if lost_run >= stop_after_loss_steps and done < steps:
            reason = "contact_lost"
            break
        if deep_stop is not None:
            hit, deep_run = deep_stop.step(deep_run, done - ok, rows["min_distance"][:ok])
            if hit and done < steps:
                reason = "too_deep"
                break
    overflow = max(overflow, flush())
    traces = {
        c: np.concatenate(v) if v else np.zeros((0,), np.float32) for c, v in parts.items()
    }
    return ReplayResult(traces, done, reason, overflow, _warnings(data))
