"""Build the floating ORCA v2 right hand (no tower, forearm or wrist hinge) with MjSpec (3.1.1)."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from graspstab.common.io import atomic_path, write_text
from graspstab.hand import names
from graspstab.hand.params import resolve_params

SCENE_FILE = "scene_right.xml"
HAND_XML = "hand.xml"
MESH_SUBDIR = "meshes"


def find_scene(description_dir: str | Path) -> Path:
    """The right-hand scene file, given the description root (with ``v2/``) or its ``v2/`` dir."""
    d = Path(description_dir)
    for cand in (d / "v2" / SCENE_FILE, d / SCENE_FILE):
        if cand.is_file():
            return cand
    raise FileNotFoundError(
        f"no v2/{SCENE_FILE} under {d}: pass the orcahand_description directory (the one with v2/)"
    )


def _absolute_mesh_files(spec: mujoco.MjSpec, scene: Path) -> None:
    """Make mesh paths absolute so the spec compiles wherever it goes (and saving can relocate)."""
    meshdir = Path(spec.meshdir) if spec.meshdir else Path()
    base = meshdir if meshdir.is_absolute() else scene.parent / meshdir
    for mesh in spec.meshes:
        if mesh.file:
            mesh.file = str((base / mesh.file).resolve())
    spec.meshdir = ""


def _collision_geoms(body: mujoco.MjsBody) -> list[mujoco.MjsGeom]:
    return [g for g in body.geoms if g.meshname and (g.contype or g.conaffinity)]


def _use_palm_core(spec: mujoco.MjSpec, palm: mujoco.MjsBody) -> None:
    """Point the palm collision geom at ``R-Carpals_CORE.stl``; add the visual skin if present.

    Upstream the palm geom uses the full ``R-Carpals.stl``; the local copy already uses the core.
    Both layouts therefore give the same palm collision hull and mass.
    """
    cores = _collision_geoms(palm)
    if len(cores) != 1:
        raise ValueError(
            f"expected one palm collision mesh geom in {palm.name}, found {len(cores)}"
        )
    core_mesh = spec.mesh(cores[0].meshname)
    right_dir = Path(core_mesh.file).parent
    core_file = right_dir / names.PALM_CORE_STL
    if not core_file.is_file():
        raise FileNotFoundError(f"palm core mesh {core_file} missing from the hand description")
    core_mesh.file = str(core_file)
    # The skin is (re-)added last, so both layouts give the same geom and mesh order.
    skin_file = right_dir / names.PALM_SKIN_STL
    for g in list(palm.geoms):
        if g.meshname and Path(spec.mesh(g.meshname).file).name == names.PALM_SKIN_STL:
            mesh = spec.mesh(g.meshname)
            spec.delete(g)
            spec.delete(mesh)
    if skin_file.is_file():
        mesh = spec.add_mesh(name=names.PALM_SKIN_MESH, file=str(skin_file))
        mesh.scale = core_mesh.scale
        palm.add_geom(
            default=spec.default,
            type=mujoco.mjtGeom.mjGEOM_MESH,
            meshname=names.PALM_SKIN_MESH,
            material="white",
            contype=0,
            conaffinity=0,
        )


def _drop_unused_assets(spec: mujoco.MjSpec) -> None:
    """Delete meshes/materials no kept geom uses (upstream declares meshes it does not ship)."""
    used_meshes = {g.meshname for g in spec.geoms if g.meshname}
    for mesh in list(spec.meshes):
        if mesh.name not in used_meshes:
            spec.delete(mesh)
    used_materials = {g.material for g in spec.geoms if g.material}
    for mat in list(spec.materials):
        if mat.name not in used_materials:
            spec.delete(mat)
    for tex in list(spec.textures):
        spec.delete(tex)


def build_hand_spec(
    description_dir: str | Path, params: dict[str, Any] | None = None
) -> mujoco.MjSpec:
    """The hand as an MjSpec: palm under a free-jointed ``hand_root``, 16 finger hinges and servos.

    qpos[0:7] is the palm frame's world pose (position, MuJoCo quaternion w-x-y-z).
    """
    p = resolve_params(params)
    scene = find_scene(description_dir)
    spec = mujoco.MjSpec.from_file(str(scene))
    spec.modelname = "orcahand_v2_right_floating"
    body_names = [b.name for b in spec.bodies]
    joint_names = [j.name for j in spec.joints]
    palm_name = names.require_name(p["palm_body"], body_names, "palm_body", str(scene))
    for b in p["drop_bodies"]:
        names.require_name(b, body_names, "drop_bodies entry", str(scene))
    for j in p["drop_joints"]:
        names.require_name(j, joint_names, "drop_joints entry", str(scene))
    names.require_fingers(p["fingertips"], "fingertips")
    for body in p["fingertips"].values():
        names.require_name(body, body_names, "fingertip body", str(scene))

    _absolute_mesh_files(spec, scene)
    palm = spec.body(palm_name)
    _use_palm_core(spec, palm)

    # Actuators and excludes are re-created after the palm subtree is moved (attach copies them).
    file_act = {
        a.target: (a.name, np.array(a.ctrlrange), float(a.gainprm[0]), np.array(a.forcerange))
        for a in spec.actuators
    }
    excludes = [(e.bodyname1, e.bodyname2) for e in spec.excludes]
    for a in list(spec.actuators):
        spec.delete(a)
    for e in list(spec.excludes):
        spec.delete(e)
    for j in p["drop_joints"]:
        spec.delete(spec.joint(j))

    spec.copy_during_attach = True
    root = spec.worldbody.add_body(name=names.ROOT_BODY)
    root.add_freejoint(name=names.WRIST_JOINT)
    moved = root.add_frame().attach_body(palm, "", "")
    moved.pos = [0.0, 0.0, 0.0]
    moved.quat = [1.0, 0.0, 0.0, 0.0]
    for b in list(spec.worldbody.bodies):
        if b.name != names.ROOT_BODY:
            spec.delete(b)  # the mount with tower, forearm and the original palm
    for b in p["drop_bodies"]:
        if spec.body(b) is not None:
            spec.delete(spec.body(b))
    for item in [*spec.worldbody.geoms, *spec.worldbody.lights, *spec.worldbody.sites]:
        spec.delete(item)  # floor, lights
    spec.stat.center = [0.0, 0.0, 0.05]
    spec.stat.extent = 0.25

    kept_bodies = {b.name for b in spec.bodies}
    for b1, b2 in excludes:
        if b1 in kept_bodies and b2 in kept_bodies:
            spec.add_exclude(bodyname1=b1, bodyname2=b2)

    hinges = [j.name for j in spec.joints if j.type == mujoco.mjtJoint.mjJNT_HINGE]
    if sorted(hinges) != sorted(names.FINGER_JOINTS):
        raise ValueError(
            f"{scene}: expected the 16 finger joints {', '.join(names.FINGER_JOINTS)} "
            f"after dropping "
            f"{p['drop_joints']}; found {', '.join(hinges)}"
        )
    for joint in names.FINGER_JOINTS:
        if joint not in file_act:
            raise ValueError(f"{scene}: no position actuator on finger joint {joint!r}")
        act_name, ctrlrange, kp_file, force_file = file_act[joint]
        kp = p["actuator"].get("kp")
        kp = kp_file if kp is None else float(kp)
        frc = p["actuator"].get("forcerange")
        forcerange = force_file if frc is None else np.array([-float(frc), float(frc)])
        act = spec.add_actuator(name=act_name, target=joint)
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        act.set_to_position(kp=kp)
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.ctrlrange = ctrlrange
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.forcerange = forcerange

    _drop_unused_assets(spec)
    return spec


def compile_hand(spec: mujoco.MjSpec) -> mujoco.MjModel:
    """Compile, naming the spec in the error (missing meshes are the usual cause)."""
    try:
        return spec.compile()
    except ValueError as exc:
        raise ValueError(f"hand model {spec.modelname!r} does not compile: {exc}") from exc


def save_hand(spec: mujoco.MjSpec, out_dir: str | Path) -> Path:
    """Write ``hand.xml`` plus ``meshes/`` so that the model loads from ``out_dir`` alone."""
    out = Path(out_dir)
    mesh_dir = out / MESH_SUBDIR
    mesh_dir.mkdir(parents=True, exist_ok=True)
    local = spec.copy()
    seen: dict[str, str] = {}
    for mesh in local.meshes:
        src = Path(mesh.file)
        if seen.setdefault(src.name, str(src)) != str(src):
            raise ValueError(f"two meshes share the file name {src.name}: {seen[src.name]}, {src}")
        with atomic_path(mesh_dir / src.name) as tmp:
            shutil.copyfile(src, tmp)
        mesh.file = src.name
    local.meshdir = MESH_SUBDIR
    local.modelfiledir = str(out.resolve())
    compile_hand(local)
    xml_path = out / HAND_XML
    write_text(xml_path, local.to_xml())
    return xml_path
