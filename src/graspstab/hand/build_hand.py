"""Hand stage entry point: floating ORCA MJCF, capsules, contact candidates (3.1.1-3.1.4)."""

from __future__ import annotations

import argparse
import json
import logging
import shutil
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from graspstab.common.io import save_npz, write_json
from graspstab.common.logs import setup_logging
from graspstab.common.provenance import provenance
from graspstab.hand import names
from graspstab.hand.candidates import contact_candidates
from graspstab.hand.capsules import PAIR_RULE, capsule_pairs, finger_links, fit_hand_capsules
from graspstab.hand.kinematics import CANDIDATES_FILE
from graspstab.hand.model import HAND_XML, MESH_SUBDIR, build_hand_spec, save_hand
from graspstab.hand.palm import palm_geometry
from graspstab.hand.params import DEFAULT_PARAMS, resolve_params
from graspstab.hand.surface_points import SURFACE_POINTS_FILE, hand_surface_points

__all__ = ["DEFAULT_PARAMS", "build_hand", "main"]

HAND_JSON = "hand.json"
CAPSULES_JSON = "capsules.json"
OUTPUTS = (HAND_XML, MESH_SUBDIR, HAND_JSON, CAPSULES_JSON, CANDIDATES_FILE, SURFACE_POINTS_FILE)

log = logging.getLogger("graspstab.hand")


def hand_metadata(
    model: mujoco.MjModel, params: dict[str, Any], palm: dict[str, Any]
) -> dict[str, Any]:
    """The hand.json record: names, limits, indices, palm geometry and total mass."""
    joints = list(names.FINGER_JOINTS)
    jids = [model.joint(j).id for j in joints]
    act_of_joint = {model.joint(int(model.actuator_trnid[a, 0])).name: a for a in range(model.nu)}
    fingertips = dict(params["fingertips"])
    proximal = {
        f: model.body(int(model.body_parentid[model.body(b).id])).name
        for f, b in fingertips.items()
    }
    wrist = model.joint(names.WRIST_JOINT)
    return {
        "root_body": names.ROOT_BODY,
        "wrist_joint": names.WRIST_JOINT,
        "wrist_qpos_index": list(range(int(wrist.qposadr[0]), int(wrist.qposadr[0]) + 7)),
        "wrist_convention": "qpos[0:7] = palm frame position [m] and quaternion (w, x, y, z)",
        "palm_body": params["palm_body"],
        "fingers": list(names.FINGERS),
        "joint_names": joints,
        "joint_lower": [float(model.jnt_range[j, 0]) for j in jids],
        "joint_upper": [float(model.jnt_range[j, 1]) for j in jids],
        "joint_qpos_index": {
            j: int(model.jnt_qposadr[i]) for j, i in zip(joints, jids, strict=True)
        },
        "joint_ctrl_index": {j: int(act_of_joint[j]) for j in joints},
        "actuator_names": [model.actuator(int(act_of_joint[j])).name for j in joints],
        "fingertips": fingertips,
        "proximal_bodies": proximal,
        "finger_links": finger_links(model, fingertips, params["palm_body"]),
        "grasp_focus": palm["grasp_focus"],
        "palm_normal": palm["palm_normal"],
        "palm_front_centre": palm["palm_front_centre"],
        "knuckle_centre": palm["knuckle_centre"],
        "geometry_frame": params["palm_body"],
        "total_mass": float(model.body_subtreemass[0]),
        "nq": int(model.nq),
        "nv": int(model.nv),
        "nu": int(model.nu),
    }


def build_hand(
    description_dir: str | Path,
    out_dir: str | Path,
    params: dict[str, Any] | None = None,
    log_file: str | Path | None = None,
) -> dict[str, Any]:
    """Build every hand artefact into ``out_dir`` and return the hand.json record."""
    if log_file:
        setup_logging(log_file)
    p = resolve_params(params)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if (out / MESH_SUBDIR).exists():
        shutil.rmtree(out / MESH_SUBDIR)  # no stale meshes from an earlier description
    log.info("building hand from %s", description_dir)
    spec = build_hand_spec(description_dir, p)
    xml = save_hand(spec, out)
    model = mujoco.MjModel.from_xml_path(str(xml))  # everything below uses the saved model
    log.info("hand.xml: %d bodies, nq=%d, nu=%d", model.nbody, model.nq, model.nu)

    palm = palm_geometry(model, p)
    caps = fit_hand_capsules(model, p, palm_normal=palm["palm_normal"])
    pairs = capsule_pairs(caps["capsules"])
    log.info("%d capsules, %d self-penetration pairs", len(caps["capsules"]), len(pairs))
    prov = provenance("hand", p)
    write_json(
        out / CAPSULES_JSON,
        {
            **caps,
            "pairs": pairs,
            "pair_rule": PAIR_RULE,
            "frame": "body frame of each capsule's body; metres",
            "provenance": prov,
        },
    )

    cands = contact_candidates(model, p)
    save_npz(out / CANDIDATES_FILE, **cands)
    log.info("%d contact candidates in %d regions", len(cands["points"]), len(cands["region_body"]))

    surface = hand_surface_points(model, p["surface_points"])
    save_npz(out / SURFACE_POINTS_FILE, **surface)
    log.info("%d surface points cover the colliding links", len(surface["points"]))

    meta = {**hand_metadata(model, p, palm), "provenance": prov}
    write_json(out / HAND_JSON, meta)
    return json.loads(json.dumps(meta, default=_plain))


def _plain(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(type(obj).__name__)


def main(argv: list[str] | None = None) -> int:
    """CLI: ``python -m graspstab.hand.build_hand --description-dir D --out-dir O``."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--description-dir", required=True, help="orcahand_description (with v2/)")
    ap.add_argument("--out-dir", required=True)
    ap.add_argument("--params-json", default=None, help="the hand config slice as JSON")
    ap.add_argument("--log-file", default=None)
    args = ap.parse_args(argv)
    params = json.loads(args.params_json) if args.params_json else None
    setup_logging(args.log_file)
    build_hand(args.description_dir, args.out_dir, params)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
