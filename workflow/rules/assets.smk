# Inputs through the workflow: YCB meshes and the ORCA hand description, from a configured local
# directory or the official archive (checksum-verified). Nothing is fetched at import time.

from graspstab.assets.ycb import user_mesh_sha256


rule fetch_ycb_object:
    input:
        # the user's own mesh (field 'mesh'), so editing it in place reruns the copy and all that
        # follows; none for a YCB object (local copy or download), which stays as before
        user_mesh=lambda wc: object_entry(wc).get("mesh") or [],
    output:
        mesh="resources/ycb/{object}/textured.obj",
        source="resources/ycb/{object}/source.json",
    params:
        local_dir=config["assets"]["ycb_dir"],
        url=lambda wc: config["assets"]["ycb_url"],  # a template: keep {id} unexpanded
        sha256=lambda wc: object_entry(wc).get("sha256"),
        mesh_override=lambda wc: object_entry(wc).get("mesh"),
        # the user's mesh's content (a params change reruns the job): an edit in place that kept
        # the old mtime (cp -p, rsync -a, an unpacked archive) still reruns the copy. Hashed once
        # per file per workflow load; None for a YCB object (checked against its pinned sha256)
        mesh_content=lambda wc: user_mesh_sha256(object_entry(wc).get("mesh")),
    threads: 1
    resources:
        mem_mb=500,
        runtime=15,
    log:
        "results/logs/fetch_ycb_object/{object}.log",
    benchmark:
        "results/benchmarks/fetch_ycb_object/{object}.tsv"
    script:
        "../scripts/fetch_ycb_object.py"


rule fetch_hand_description:
    input:
        # the user's own checksum manifest (assets.hand_manifest), if any: editing it refetches
        manifest=config["assets"]["hand_manifest"] or [],
    output:
        directory("resources/orcahand_description"),
    params:
        local_dir=config["assets"]["hand_dir"],
        url=lambda wc: config["assets"]["hand_url"],  # a template: keep {commit} unexpanded
        commit=config["assets"]["hand_commit"],
    threads: 1
    resources:
        mem_mb=500,
        runtime=15,
    log:
        "results/logs/fetch_hand_description/hand.log",
    benchmark:
        "results/benchmarks/fetch_hand_description/hand.tsv"
    script:
        "../scripts/fetch_hand_description.py"
