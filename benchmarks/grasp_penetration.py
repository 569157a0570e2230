"""How deep synthesised grasps penetrate their object, and how close their fingertips come.

Two views of the annealed grasps (3.1.4), per object:

* against the true (repaired) mesh, from the shard tables: the deepest hand surface point
  (``max_hand_depth``, exact-distance grid) and the fingertips within 5 mm of the surface;
* by MuJoCo's own collision check: the hand (hand.xml) and the object (object.xml, its CoACD
  parts) are put in one scene at each grasp's pose and ``mj_forward``'s deepest hand-object contact
  is taken. MuJoCo collides the convex hull of each part, which can bulge beyond the true surface
  (most where CoACD bridges a cavity: the mug's), so the script also prints how far the part hulls
  reach outside the mesh (95th percentile and maximum of 3000 samples per part).

    python benchmarks/grasp_penetration.py <workdir>
"""

from __future__ import annotations

import argparse
import collections
from pathlib import Path

import mujoco
import numpy as np
import polars as pl
import trimesh

from graspstab.common.io import read_json
from graspstab.objects.sdf import exact_signed_distance

FINGERS = ("thumb", "index", "middle", "ring", "little")


def scene(workdir: Path, object_id: str) -> tuple[mujoco.MjModel, int]:
    """The hand plus the object's body (prefixed ``obj_``) in one compiled model."""
    spec = mujoco.MjSpec.from_file(str(workdir / "results" / "hand" / "hand.xml"))
    obj = mujoco.MjSpec.from_file(str(workdir / "results" / "objects" / object_id / "object.xml"))
    spec.worldbody.add_frame().attach_body(obj.body("object"), "obj_", "")
    model = spec.compile()
    return model, model.body("obj_object").id


def deepest_contacts(
    model: mujoco.MjModel, object_body: int, grasps: pl.DataFrame, joint_qpos: list[int]
) -> tuple[np.ndarray, collections.Counter]:
    """Per grasp the most negative hand-object contact distance [m]; bodies deeper than 5 mm."""
    data = mujoco.MjData(model)
    depths, bodies = [], collections.Counter()
    for row in grasps.iter_rows(named=True):
        data.qpos[:] = model.qpos0
        data.qpos[0:3] = [row[f"wrist_{a}"] for a in "xyz"]
        data.qpos[3:7] = [row[f"quat_{a}"] for a in "wxyz"]
        data.qpos[joint_qpos] = [row[f"theta_{k:02d}"] for k in range(16)]
        mujoco.mj_forward(model, data)
        worst: dict[str, float] = {}
        for c in data.contact[: data.ncon]:
            b1, b2 = model.geom_bodyid[c.geom1], model.geom_bodyid[c.geom2]
            if object_body in (b1, b2):
                name = model.body(b2 if b1 == object_body else b1).name
                worst[name] = min(worst.get(name, 0.0), float(c.dist))
        depths.append(min(worst.values(), default=0.0))
        bodies.update(k for k, v in worst.items() if v < -0.005)
    return np.asarray(depths), bodies


def part_bulge(object_dir: Path) -> np.ndarray:
    """Signed distance to the mesh [m] of surface samples of every CoACD part's convex hull."""
    mesh = trimesh.load(object_dir / "mesh.obj", force="mesh", process=False)
    with np.load(object_dir / "convex_parts.npz") as parts:
        hulls = [
            trimesh.Trimesh(parts[f"vertices_{i}"], parts[f"faces_{i}"]).convex_hull
            for i in range(int(parts["count"]))
        ]
    samples = np.concatenate([trimesh.sample.sample_surface(h, 3000, seed=0)[0] for h in hulls])
    return exact_signed_distance(mesh, samples)


def main() -> None:
    """Print the penetration figures of every object with grasp tables in the work directory."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdir", type=Path)
    args = ap.parse_args()
    hand = read_json(args.workdir / "results" / "hand" / "hand.json")
    joint_qpos = [hand["joint_qpos_index"][j] for j in hand["joint_names"]]
    print(
        "                        true mesh [mm]                 MuJoCo contacts [mm]"
        "           CoACD bulge [mm]\n"
        f"{'object':22s} grasps  depth q50  q95  tips<5mm  |tip| q50  "
        "depth q50  worst  >5 mm  p95  max  most involved bodies"
    )
    for obj_dir in sorted((args.workdir / "results" / "grasps").iterdir()):
        tables = sorted(obj_dir.glob("shard_*.parquet"))
        if not tables:
            continue
        grasps = pl.concat([pl.read_parquet(t) for t in tables])
        model, body = scene(args.workdir, obj_dir.name)
        depths, bodies = deepest_contacts(model, body, grasps, joint_qpos)
        mm = depths * 1000
        top = ", ".join(f"{b.removeprefix('right_')}:{n}" for b, n in bodies.most_common(3))
        true_depth = grasps["max_hand_depth"].to_numpy() * 1000
        tips = np.abs(np.stack([grasps[f"tip_dist_{f}"].to_numpy() for f in FINGERS], 1)) * 1000
        bulge = part_bulge(args.workdir / "results" / "objects" / obj_dir.name) * 1000
        print(
            f"{obj_dir.name:22s} {len(mm):6d}  {np.median(true_depth):9.1f} "
            f"{np.percentile(true_depth, 95):4.1f}  {np.median((tips < 5).sum(1)):8.0f}  "
            f"{np.median(tips):9.1f}  {np.median(mm):9.1f}  {mm.min():5.1f}  "
            f"{np.mean(mm < -5):5.2f}  {np.percentile(bulge, 95):3.1f}  {bulge.max():4.1f}  {top}"
        )


if __name__ == "__main__":
    main()
