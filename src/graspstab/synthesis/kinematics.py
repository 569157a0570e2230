"""Batched torch forward kinematics of the built hand, so the annealer poses many grasps at once.

Grasp synthesis (thesis 3.1.3-3.1.4) evaluates g = (P, R, theta) (eq. 2) for a whole batch of chains
per step; MuJoCo's ``mj_kinematics`` poses one hand at a time. This module reads the hand stage's
artefacts (``hand.xml``, ``hand.json``, ``capsules.json``, ``contact_candidates.npz``,
``surface_points.npz``) once and
poses B hands with a handful of batched tensor operations:

* every body's local transform (4 x 4, parent frame) is an affine function of ``sin(q)`` and
  ``1 - cos(q)`` of its hinge angle (Rodrigues), so all of them come from three constant tables in
  one shot, with MuJoCo's off-centre joint anchors (``jnt_pos``) folded in;
* bodies are grouped by tree depth and each depth is one batched product with its parents' poses
  (five products for the ORCA hand), never a Python loop over grasps or bodies;
* the contact candidates (3.1.2), hand surface points, capsule ends, palm box centre, grasp focus
  and palm normal are
  homogeneous points/directions of their bodies, mapped to the world by one batched GEMM per kind.

Internally frames are stored grasp-last (``[body, column, row, grasp]``), which turns the tiny
3 x 3 products into broadcasts and GEMMs over contiguous grasp vectors (several times faster than
batches of 3 x 3 matrices on CPU). The returned tensors have the documented (B, ...) shapes as
views of that layout; call ``.contiguous()`` where a caller needs contiguous memory.

The wrist pose is the pose of the root body ``hand_root`` (MuJoCo's ``qpos[0:7]``), its rotation
given in the continuous 6-D form of 3.1.1. Everything is differentiable.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import torch
from torch import Tensor

from graspstab.common.io import load_npz, read_json
from graspstab.synthesis.rotation import rot6d_to_matrix

HAND_XML = "hand.xml"
HAND_JSON = "hand.json"
CAPSULES_JSON = "capsules.json"
CANDIDATES_NPZ = "contact_candidates.npz"
SURFACE_NPZ = "surface_points.npz"


@dataclass
class HandPose:
    """World-frame geometry of a batch of B hands (inputs' dtype; views, see the module doc)."""

    body_pos: Tensor  # (B, nbody, 3) body origins; index = MuJoCo body id (0 = world)
    body_rot: Tensor  # (B, nbody, 3, 3) body rotations (columns = body axes in world)
    candidates: Tensor  # (B, 120, 3) contact candidates p_i (3.1.2)
    candidate_normals: Tensor  # (B, 120, 3) their outward unit normals
    surface_points: Tensor  # (B, S, 3) points covering the links' collision hulls (for E_hpen)
    capsule_p0: Tensor  # (B, K, 3) capsule segment ends, capsules.json order
    capsule_p1: Tensor  # (B, K, 3)
    box_center: Tensor  # (B, 3) palm box centre
    box_rot: Tensor  # (B, 3, 3) palm box axes (columns) in world
    grasp_focus: Tensor  # (B, 3) grasp-focus point (3.1.3)
    palm_normal: Tensor  # (B, 3) palm normal (unit), the side the fingers close towards
    wrist_rot: Tensor  # (B, 3, 3) rotation of hand_root, from the 6-D input


@dataclass(frozen=True)
class _PointGroup:
    """Homogeneous points of several bodies, padded per body for one batched product."""

    rows: Tensor  # (nr,) rows of the stacked frames (one per body)
    points: np.ndarray  # (nr, kmax, 4) body-frame points (w = 1) or directions (w = 0), padded
    flat: Tensor | None  # (N,) rows of the padded result in the input order; None if identity


def _point_group(points_h: np.ndarray, rows: np.ndarray) -> _PointGroup:
    """Group homogeneous points (N, 4) by frame row, padding each body to the largest count."""
    unique = list(dict.fromkeys(int(r) for r in rows))
    members = [np.flatnonzero(rows == r) for r in unique]
    kmax = max(len(m) for m in members)
    padded = np.zeros((len(unique), kmax, 4))
    flat = np.empty(len(rows), dtype=np.int64)
    for g, idx in enumerate(members):
        padded[g, : len(idx)] = points_h[idx]
        flat[idx] = g * kmax + np.arange(len(idx))
    identity = len(flat) == len(unique) * kmax and np.array_equal(flat, np.arange(len(flat)))
    return _PointGroup(
        rows=torch.as_tensor(unique, dtype=torch.long),
        points=padded,
        flat=None if identity else torch.as_tensor(flat, dtype=torch.long),
    )


@dataclass(frozen=True)
class _Tables:
    """The constant tables of :class:`BatchedHandKinematics` in one dtype/device."""

    local_a: Tensor  # (nb, 4, 4, 1) constant part of each non-root body's local transform
    local_s: Tensor  # (nb, 4, 4, 1) coefficient of sin(q)
    local_c: Tensor  # (nb, 4, 4, 1) coefficient of 1 - cos(q)
    qpos0: Tensor  # (nb, 1) joint reference angle (0 for jointless bodies)
    groups: dict[str, Tensor]  # name -> (nr, kmax, 4) padded body-frame points
    box_rot_local_t: Tensor  # (3, 3) palm box axes in its body frame, transposed


def _quat_to_mat(quat: np.ndarray) -> np.ndarray:
    """3 x 3 rotation of a MuJoCo quaternion (w, x, y, z)."""
    out = np.zeros(9)
    mujoco.mju_quat2Mat(out, np.asarray(quat, dtype=np.float64))
    return out.reshape(3, 3)


def _skew(v: np.ndarray) -> np.ndarray:
    """[v]x, the cross-product matrix of a 3-vector (eq. 8)."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _load_json(path: Path) -> dict:
    if not path.is_file():
        raise FileNotFoundError(f"{path} not found: pass the hand stage's output directory")
    return read_json(path)


def _load_points(path: Path, *extra: str) -> dict:
    """Body-frame ``points`` (float64), ``extra`` arrays and ``body`` names of a hand npz."""
    if not path.is_file():
        raise FileNotFoundError(
            f"{path} not found: pass the hand stage's output directory (rule build_hand)"
        )
    npz = load_npz(path)
    out = {k: np.asarray(npz[k], dtype=np.float64) for k in ("points", *extra)}
    out["body"] = [str(b) for b in npz["body"]]
    return out


class BatchedHandKinematics:
    """Batched forward kinematics of ``hand_dir/hand.xml`` and its grasp-synthesis geometry."""

    def __init__(self, hand_dir: str | Path, dtype: torch.dtype = torch.float32) -> None:
        self.hand_dir = Path(hand_dir)
        xml = self.hand_dir / HAND_XML
        if not xml.is_file():
            raise FileNotFoundError(f"{xml} not found: pass the hand stage's output directory")
        hand = _load_json(self.hand_dir / HAND_JSON)
        caps = _load_json(self.hand_dir / CAPSULES_JSON)
        cand_path = self.hand_dir / CANDIDATES_NPZ
        cands = _load_points(cand_path, "normals")
        cand_points, cand_normals, cand_bodies = cands["points"], cands["normals"], cands["body"]
        surface = _load_points(self.hand_dir / SURFACE_NPZ)
        surface_points, surface_bodies = surface["points"], surface["body"]

        model = mujoco.MjModel.from_xml_path(str(xml))
        self.model = model
        self.dtype = dtype
        self.nbody = int(model.nbody)
        self.body_names: list[str] = [model.body(i).name for i in range(self.nbody)]
        self.joint_names: list[str] = list(hand["joint_names"])
        self.root_body: str = hand.get("root_body", "hand_root")
        self.palm_body: str = hand["palm_body"]
        self._root = self.body_index(self.root_body)
        self._check_root(model)
        joint_of_body = self._hinge_table(model)

        # --- depth levels (3.1.1: one batched product per tree depth) ---
        depth = np.zeros(self.nbody, dtype=int)
        for b in range(1, self.nbody):
            depth[b] = depth[model.body_parentid[b]] + 1
        subtree = self._descendants(model, self._root)
        if len(subtree) != self.nbody - 1:
            raise ValueError(f"{xml}: every body except world must lie under {self.root_body!r}")
        levels = [
            subtree[depth[subtree] == d]
            for d in range(depth[self._root] + 1, int(depth[subtree].max()) + 1)
        ]
        self._levels = levels
        # row of each body in the concatenation [world, root, level 1, level 2, ...]
        order = np.concatenate([[0, self._root], *levels]).astype(int)
        row_of = np.empty(self.nbody, dtype=int)
        row_of[order] = np.arange(self.nbody)
        self._perm = torch.as_tensor(row_of, dtype=torch.long)  # body id -> row
        # parent's index within the previous level (the root level is [root])
        prev = np.array([self._root])
        self._parent_local: list[Tensor | None] = []
        for ids in levels:
            pos_in_prev = {int(b): i for i, b in enumerate(prev)}
            parents = [pos_in_prev[int(model.body_parentid[b])] for b in ids]
            self._parent_local.append(
                None if len(prev) == 1 else torch.as_tensor(parents, dtype=torch.long)
            )
            prev = ids
        nonroot = np.concatenate(levels) if levels else np.zeros(0, dtype=int)
        self._nonroot = nonroot

        # --- local transforms [[M, e], [0, 1]] = A + sin(q) S + (1 - cos(q)) C ---
        # Rodrigues about the joint axis through MuJoCo's joint anchor a (jnt_pos), as in
        # mj_kinematics: M = R_l (I + s K + (1 - c) K^2), e = t_l + R_l a - M a.
        nb = len(nonroot)
        a_tab, s_tab, c_tab = np.zeros((nb, 4, 4)), np.zeros((nb, 4, 4)), np.zeros((nb, 4, 4))
        a_tab[:, 3, 3] = 1.0
        qpos0 = np.zeros(nb)
        self._angle_index = np.full(nb, len(self.joint_names), dtype=int)  # -> padded zero
        for k, b in enumerate(nonroot):
            r_local = _quat_to_mat(model.body_quat[b])
            t_local = np.asarray(model.body_pos[b], dtype=np.float64)
            j = joint_of_body.get(int(b))
            if j is None:
                a_tab[k, :3, :3], a_tab[k, :3, 3] = r_local, t_local
                continue
            jid, jpos = j
            anchor = np.asarray(model.jnt_pos[jid], dtype=np.float64)
            axis = np.asarray(model.jnt_axis[jid], dtype=np.float64)
            kx = _skew(axis / np.linalg.norm(axis))
            for tab, mat in ((a_tab, np.eye(3)), (s_tab, kx), (c_tab, kx @ kx)):
                m = r_local @ mat
                tab[k, :3, :3] = m
                tab[k, :3, 3] = -m @ anchor
            a_tab[k, :3, 3] += t_local + r_local @ anchor
            qpos0[k] = model.qpos0[model.jnt_qposadr[jid]]
            self._angle_index[k] = jpos
        self._angle_index_t = torch.as_tensor(self._angle_index, dtype=torch.long)

        # --- hand.json limits and palm geometry (palm frame -> root frame via the fixed offset) ---
        self._joint_lower = np.asarray(hand["joint_lower"], dtype=np.float64)
        self._joint_upper = np.asarray(hand["joint_upper"], dtype=np.float64)
        palm = self.body_index(self.palm_body)
        r_root_palm, p_root_palm = self._fixed_offset(model, palm, joint_of_body)
        palm_normal = np.asarray(hand["palm_normal"], dtype=np.float64)
        palm_normal = palm_normal / np.linalg.norm(palm_normal)
        focus_palm = np.asarray(hand["grasp_focus"], dtype=np.float64)
        self._palm_normal_root = r_root_palm @ palm_normal
        self._grasp_focus_root = p_root_palm + r_root_palm @ focus_palm

        # --- capsules and palm box (capsules.json, body frames) ---
        capsules = caps["capsules"]
        self.capsule_names: list[str] = [c["name"] for c in capsules]
        cap_body = np.array([self.body_index(c["body"]) for c in capsules], dtype=int)
        cap_p0 = np.array([c["p0"] for c in capsules], dtype=np.float64).reshape(-1, 3)
        cap_p1 = np.array([c["p1"] for c in capsules], dtype=np.float64).reshape(-1, 3)
        self._capsule_radii = np.array([c["radius"] for c in capsules], dtype=np.float64)
        box = caps["palm_box"]
        box_body = self.body_index(box["body"])
        self._box_rot_local = np.asarray(box["rotation"], dtype=np.float64).reshape(3, 3)
        self._box_half_extents = np.asarray(box["half_extents"], dtype=np.float64)
        self._pairs = np.asarray(caps["pairs"], dtype=np.int64).reshape(-1, 2)
        self.capsule_body = torch.as_tensor(cap_body, dtype=torch.long)
        self.box_body = box_body

        # --- contact candidates (3.1.2) ---
        if cand_points.shape != cand_normals.shape or cand_points.shape[1:] != (3,):
            raise ValueError(f"{cand_path}: points/normals must both be (N, 3)")
        cand_body = np.array([self.body_index(b) for b in cand_bodies], dtype=int)
        self.candidate_body = torch.as_tensor(cand_body, dtype=torch.long)
        self.n_candidates = len(cand_body)
        surface_body = np.array([self.body_index(b) for b in surface_bodies], dtype=int)
        self.surface_body = torch.as_tensor(surface_body, dtype=torch.long)
        self.n_surface_points = len(surface_body)
        self.n_capsules = len(capsules)

        # homogeneous points (w = 1) and directions (w = 0), grouped by body for batched products
        def homogeneous(v: np.ndarray, w: float) -> np.ndarray:
            return np.c_[np.asarray(v, dtype=np.float64).reshape(-1, 3), np.full(len(v), w)]

        extras = np.array([box["center"], focus_palm, palm_normal])
        specs = {
            "candidates": (homogeneous(cand_points, 1.0), cand_body),
            "normals": (homogeneous(cand_normals, 0.0), cand_body),
            "surface": (homogeneous(surface_points, 1.0), surface_body),
            "p0": (homogeneous(cap_p0, 1.0), cap_body),
            "p1": (homogeneous(cap_p1, 1.0), cap_body),
            # palm box centre, grasp focus (points) and palm normal (a direction)
            "extras": (
                np.c_[extras, [1.0, 1.0, 0.0]],
                np.array([box_body, palm, palm]),
            ),
        }
        self._groups = {k: _point_group(h, row_of[b]) for k, (h, b) in specs.items()}
        self._box_row = int(row_of[box_body])
        self._np_tables = {
            "local_a": a_tab[..., None],
            "local_s": s_tab[..., None],
            "local_c": c_tab[..., None],
            "qpos0": qpos0[:, None],
            "box_rot_local_t": self._box_rot_local.T.copy(),
        }
        self._cache: dict[tuple[torch.dtype, torch.device], _Tables] = {}

        # public constant tensors in the constructor's dtype
        self.capsule_radii = torch.as_tensor(self._capsule_radii, dtype=dtype)
        self.box_half_extents = torch.as_tensor(self._box_half_extents, dtype=dtype)
        self.pairs = torch.as_tensor(self._pairs, dtype=torch.long)
        self.joint_lower = torch.as_tensor(self._joint_lower, dtype=dtype)
        self.joint_upper = torch.as_tensor(self._joint_upper, dtype=dtype)
        self.palm_normal_root = torch.as_tensor(self._palm_normal_root, dtype=dtype)
        self.grasp_focus_root = torch.as_tensor(self._grasp_focus_root, dtype=dtype)

    # ----------------------------------------------------------------------------- construction

    def body_index(self, name: str) -> int:
        """MuJoCo body id of ``name`` (= its row in HandPose.body_pos); errors list the names."""
        try:
            return self.body_names.index(name)
        except ValueError:
            raise KeyError(
                f"{self.hand_dir / HAND_XML}: no body {name!r}; bodies are {self.body_names}"
            ) from None

    def _check_root(self, model: mujoco.MjModel) -> None:
        """The root must hang from the world and carry exactly one free joint (the wrist)."""
        r = self._root
        ok = (
            model.body_parentid[r] == 0
            and model.body_jntnum[r] == 1
            and model.jnt_type[model.body_jntadr[r]] == mujoco.mjtJoint.mjJNT_FREE
        )
        if not ok:
            raise ValueError(
                f"{self.hand_dir / HAND_XML}: root body {self.root_body!r} must be a child of the "
                "world carrying one free joint (the wrist, qpos[0:7])"
            )

    def _hinge_table(self, model: mujoco.MjModel) -> dict[int, tuple[int, int]]:
        """body id -> (joint id, index in joint_names) of the finger hinges; checks the model."""
        if len(self.joint_names) != 16:
            raise ValueError(f"{self.hand_dir / HAND_JSON}: joint_names must list 16 finger joints")
        model_joints = [model.joint(j).name for j in range(model.njnt)]
        table: dict[int, tuple[int, int]] = {}
        for pos, name in enumerate(self.joint_names):
            if name not in model_joints:
                raise KeyError(
                    f"{self.hand_dir / HAND_JSON}: joint_names has {name!r}, not in hand.xml "
                    f"(joints: {model_joints})"
                )
            jid = model_joints.index(name)
            if model.jnt_type[jid] != mujoco.mjtJoint.mjJNT_HINGE:
                raise ValueError(f"{self.hand_dir / HAND_XML}: joint {name!r} is not a hinge")
            table[int(model.jnt_bodyid[jid])] = (jid, pos)
        for b in range(1, model.nbody):
            if b == self._root:
                continue
            n = int(model.body_jntnum[b])
            if n > 1 or (n == 1 and b not in table):
                raise ValueError(
                    f"{self.hand_dir / HAND_XML}: body {self.body_names[b]!r} has joints other "
                    "than one hinge listed in hand.json joint_names; not supported"
                )
        return table

    def _descendants(self, model: mujoco.MjModel, root: int) -> np.ndarray:
        """Body ids in the subtree of ``root`` (root included)."""
        out = [root]
        for b in range(root + 1, model.nbody):
            if model.body_parentid[b] in out:
                out.append(b)
        return np.array(out)

    def _fixed_offset(
        self, model: mujoco.MjModel, body: int, joint_of_body: dict[int, tuple[int, int]]
    ) -> tuple[np.ndarray, np.ndarray]:
        """Pose (R, p) of ``body`` in the root frame; the chain to the root must be jointless."""
        rot, pos = np.eye(3), np.zeros(3)
        b = body
        while b != self._root:
            if b in joint_of_body or b == 0:
                raise ValueError(
                    f"{self.hand_dir / HAND_XML}: body {self.body_names[body]!r} must be rigidly "
                    f"attached to {self.root_body!r} (a joint lies between them)"
                )
            r_local = _quat_to_mat(model.body_quat[b])
            rot, pos = r_local @ rot, r_local @ pos + model.body_pos[b]
            b = int(model.body_parentid[b])
        return rot, pos

    def _tables(self, dtype: torch.dtype, device: torch.device) -> _Tables:
        key = (dtype, device)
        if key not in self._cache:
            t = {
                k: torch.as_tensor(v, dtype=dtype, device=device)
                for k, v in self._np_tables.items()
            }
            groups = {
                k: torch.as_tensor(g.points, dtype=dtype, device=device)
                for k, g in self._groups.items()
            }
            self._cache[key] = _Tables(groups=groups, **t)
        return self._cache[key]

    # ----------------------------------------------------------------------------- kinematics

    def forward(self, wrist_pos: Tensor, rot6d: Tensor, joints: Tensor) -> HandPose:
        """Pose B hands: wrist position (B, 3), 6-D wrist rotation (B, 6), joints (B, 16).

        ``wrist_pos`` and the rotation are the pose of ``hand_root`` (MuJoCo ``qpos[0:7]``); joints
        are in hand.json ``joint_names`` order [rad]. Computation uses ``wrist_pos``'s dtype/device.
        """
        batch = wrist_pos.shape[0]
        if (
            wrist_pos.shape != (batch, 3)
            or rot6d.shape != (batch, 6)
            or joints.shape != (batch, len(self.joint_names))
        ):
            raise ValueError(
                "forward expects wrist_pos (B, 3), rot6d (B, 6), joints (B, 16); got "
                f"{tuple(wrist_pos.shape)}, {tuple(rot6d.shape)}, {tuple(joints.shape)}"
            )
        dtype, device = wrist_pos.dtype, wrist_pos.device
        tab = self._tables(dtype, device)
        rot6d, joints = rot6d.to(dtype), joints.to(dtype)

        # Frames are kept grasp-last, F[row, j, i, b] = component i of column j of [R | p] of
        # grasp b, so every product below is a broadcast or a GEMM over contiguous batches.
        wrist_rot = rot6d_to_matrix(rot6d)
        root = torch.cat((wrist_rot.permute(2, 1, 0), wrist_pos.T[None]), dim=0)[None]
        # all local transforms at once: A + sin(q) S + (1 - cos(q)) C, (nb, 4, 4, B)
        padded = torch.cat((joints.T, joints.new_zeros(1, batch)), dim=0)
        angle = padded.index_select(0, self._angle_index_t.to(device)) - tab.qpos0
        sin = torch.sin(angle)[:, None, None]
        vers = (1.0 - torch.cos(angle))[:, None, None]
        local = tab.local_a + sin * tab.local_s + vers * tab.local_c

        frames = [root]
        parent, start = root, 0
        for ids, parent_idx in zip(self._levels, self._parent_local, strict=True):
            n = len(ids)
            if parent_idx is not None:
                parent = parent.index_select(0, parent_idx.to(device))
            # child column k = sum_j parent column j * local[j, k] (row 3 of local carries p)
            loc = local[start : start + n]
            child = (parent[:, :, None] * loc[:, :, :, None]).sum(dim=1)
            frames.append(child)
            parent, start = child, start + n
        world = torch.eye(4, 3, dtype=dtype, device=device)[None, :, :, None]
        stacked = torch.cat([world.expand(1, 4, 3, batch), *frames], dim=0)

        def points(name: str) -> Tensor:
            """World points of a group, (B, N, 3): one gather of frames, one batched GEMM."""
            group = self._groups[name]
            frame = stacked.index_select(0, group.rows.to(device)).reshape(-1, 4, 3 * batch)
            out = torch.bmm(tab.groups[name], frame).reshape(-1, 3, batch)
            if group.flat is not None:
                out = out.index_select(0, group.flat.to(device))
            return out.permute(2, 0, 1)

        poses = stacked.index_select(0, self._perm.to(device))  # body id order
        box_frame = stacked[self._box_row, :3].reshape(3, 3 * batch)
        box_rot = (tab.box_rot_local_t @ box_frame).reshape(3, 3, batch).permute(2, 1, 0)
        extras = points("extras")
        return HandPose(
            body_pos=poses[:, 3].permute(2, 0, 1),
            body_rot=poses[:, :3].permute(3, 0, 2, 1),
            candidates=points("candidates"),
            candidate_normals=points("normals"),
            surface_points=points("surface"),
            capsule_p0=points("p0"),
            capsule_p1=points("p1"),
            box_center=extras[:, 0],
            box_rot=box_rot,
            grasp_focus=extras[:, 1],
            palm_normal=extras[:, 2],
            wrist_rot=wrist_rot,
        )

    __call__ = forward
