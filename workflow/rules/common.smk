# Configuration (Hydra compose + schema validation, once at load time) and input functions.

import functools
from pathlib import Path

from graspstab.common.units import ms_of
from graspstab.evaluation.splits import sample_assignments
from graspstab.replay import protocols
from graspstab.replay.protocols import replay_params
from graspstab.sensing.conditions import training_label

from graspstab.config import ConfigError, creep_free_seeds, load_config, shards_of

_raw_overrides = dict(config)
try:
    _resolved = load_config(
        config_dir=Path(workflow.basedir) / "config",
        schema_path=Path(workflow.basedir) / "workflow" / "schemas" / "config.schema.yaml",
        snakemake_config=_raw_overrides,
    )
except ConfigError as exc:
    raise WorkflowError(f"graspstab configuration error: {exc}") from None
config.clear()
config.update(_resolved)


wildcard_constraints:
    object=r"[0-9]{3}(-[a-z])?_[a-z0-9_]+",
    shard=r"[0-9]+",


def object_ids():
    """The objects this run covers: the object set, or its only_objects subset."""
    items = config["objects"]["items"]
    only = config["only_objects"]
    return [o for o in items if only is None or o in only]


def object_entry(wildcards):
    """The object's config entry (split, mass, sha256, optional mesh and rotation)."""
    return config["objects"]["items"][wildcards.object]


def object_outputs(name):
    """One preprocessed artefact for every object of the run."""
    return expand("results/objects/{object}/{name}", object=object_ids(), name=name)


def synthesis_params():
    """What a shard's result depends on: everything in the synthesis group but the shard counts
    (adding shards must not rerun the existing ones)."""
    return {k: v for k, v in config["synthesis"].items() if k not in ("shards", "split_shards")}


def shard_tables_of(objects):
    """Every shard table of the given objects (synthesis.shards, or the split's split_shards)."""
    return [
        f"results/grasps/{o}/shard_{k}.parquet" for o in objects for k in range(shards_of(config, o))
    ]


def shard_tables(wildcards):
    """All shard tables of one object."""
    return shard_tables_of([wildcards.object])


def grasp_outputs(name):
    """One synthesis artefact for every object of the run."""
    return expand("results/grasps/{object}/{name}", object=object_ids(), name=name)


# Window datasets (dataset.smk).


def replay_outputs(kind, root="results"):
    """Every replay table (kind "replays", .parquet) or trace file (kind "traces", .npz), of the
    main run or of the creep-free benchmark (root results/creep_free)."""
    ext = "parquet" if kind == "replays" else "npz"
    return [
        f"{root}/replay/{o}/{kind}_{k}.{ext}"
        for o in object_ids()
        for k in range(shards_of(config, o))
    ]


def replay_keys(root="results"):
    """(object, shard) of every trace file of replay_outputs("traces"), in the same order."""
    return [[o, k] for o in object_ids() for k in range(shards_of(config, o))]


def sensing_seeds():
    """The baseline seeds the sensor-robustness study scores (sensing.seeds, else every one)."""
    return list(config["sensing"]["seeds"] or config["train"]["seeds"])


def augmented_runs(name):
    """The sensor-augmented training runs' files (sensing.augment's modes x families x seeds)."""
    aug = config["sensing"]["augment"]
    return expand(
        f"results/train/sensing/{{mode}}/{{model}}/seed{{seed}}/{name}",
        mode=aug["modes"],
        model=aug["families"],
        seed=aug["seeds"] or sensing_seeds(),
    )


def augment_sensing(mode):
    """The part of the sensing group an augmented training of ``mode`` reads (so that changing
    the scored seeds or families reruns no training): the mixture reads every curve and preset,
    a corruption's mode its own curve only."""
    sensing = config["sensing"]
    mixture = mode == "mixture"
    return {
        "full_scale_n": sensing["full_scale_n"],
        "curves": sensing["curves"] if mixture else {mode: sensing["curves"].get(mode, [])},
        "presets": sensing["presets"] if mixture else {},
        "augment": {"clean_share": sensing["augment"]["clean_share"], "mode": mode},
    }


def augmented_keys():
    """(family, seed, training) of every augmented run, in augmented_runs' order."""
    aug = config["sensing"]["augment"]
    return [
        {"family": m, "seed": s, "training": training_label(mode)}
        for mode in aug["modes"]
        for m in aug["families"]
        for s in aug["seeds"] or sensing_seeds()
    ]


def pick_seeds():
    """The sweep seeds the pick-window robustness scores: the scored baseline seeds the sweep
    also trained, else its first."""
    sweep = list(config["sweep"]["seeds"])
    return [s for s in sensing_seeds() if s in sweep] or sweep[:1]


def pick_runs(name):
    """Each family's sweep runs at the monitor's window (4.5's latency-aware pick), pick_seeds."""
    return sweep_runs(name, pick_seeds(), windows_ms=[ms_of(config["monitor"]["window_s"])])


def audit_runs():
    """(input set, metrics.json) of every input-audit run: the baseline runs as "forces", then
    each of audit.sets, for audit.families x audit.seeds (default: every training seed)."""
    audit = config["audit"]
    seeds = audit["seeds"] or config["train"]["seeds"]
    out = [
        ("forces", f"results/train/baseline/{m}/seed{s}/metrics.json")
        for m in audit["families"]
        for s in seeds
    ]
    return out + [
        (i, f"results/train/inputs/{i}/{m}/seed{s}/metrics.json")
        for i in audit["sets"]
        for m in audit["families"]
        for s in seeds
    ]


# The input audit's artefacts the report reads (set by audit.smk when it runs).
AUDIT_ARTEFACTS = {}
# The k-fold study's artefacts per protocol (crossval.smk), empty unless it is enabled.
CROSSVAL_ARTEFACTS = {}
# The closed loop's summaries per protocol (closed_loop.smk), empty unless it is enabled.
CLOSED_LOOP_ARTEFACTS = {}


# The sensor-robustness study's artefacts the report reads (set by sensing.smk when it runs).
SENSING_ARTEFACTS = {}


def object_splits():
    """The split of every object of the run (3.5.1)."""
    return {o: config["objects"]["items"][o]["split"] for o in object_ids()}


def sweep_ms():
    """The sweep's window lengths in whole milliseconds (the wildcard of trim_sweep_window)."""
    return [ms_of(w) for w in config["sweep"]["windows_s"]]


def dataset_params(window_s):
    """What a dataset depends on: labelling rules, splits, time step, seed and its window."""
    return {
        "labels": config["labels"],
        "splits": object_splits(),
        "dt": config["replay"]["timestep"],
        "seed": config["seed"],
        "window_s": window_s,
    }


# The creep-free benchmark (creep_free.smk).

CREEP_FREE = "results/creep_free"
# The benchmark's artefacts the report reads (set by creep_free.smk when it is enabled).
CREEP_FREE_ARTEFACTS = {}


def creep_free_replay():
    """The creep-free benchmark's replay params (replay.protocols.creep_free_replay)."""
    return protocols.creep_free_replay(config)


def creep_free_labels():
    """The creep-free benchmark's labelling rules (replay.protocols.creep_free_labels)."""
    return protocols.creep_free_labels(config)


def creep_free_dataset_params(window_s):
    """dataset_params of the creep-free benchmark: its own labelling rules."""
    return {**dataset_params(window_s), "labels": creep_free_labels()}


def creep_free_sweep_ms():
    """The creep-free sweep's window lengths in whole milliseconds."""
    return [ms_of(w) for w in config["creep_free"]["sweep_windows_s"]]


# The streaming monitor (monitor.smk).


def held_out_replays(kind, root="results"):
    """The replay tables or trace files of the validation and test objects (3.5.1)."""
    held_out = {o for o, s in object_splits().items() if s in ("val", "test")}
    return [p for p in replay_outputs(kind, root) if Path(p).parent.name in held_out]


def sweep_first_seed(model, ms, name, root="results"):
    """One file of a sweep configuration's first-seed run (the run the monitor and export use)."""
    seeds = creep_free_seeds(config, "sweep") if root == CREEP_FREE else config["sweep"]["seeds"]
    seed = seeds[0]
    return f"{root}/train/sweep/{model}/w{ms}ms/seed{seed}/{name}"


# Learning studies (train.smk).

MODELS = ["cnn", "gru", "lstm"]
# timing.json: the run's training seconds, a sidecar (they differ on every run), not data
RUN_FILES = {"metrics": "metrics.json", "predictions": "predictions.parquet",
             "timing": "timing.json"}


def dataset_inputs(directory):
    """Every file of a window dataset that training and its test read (graspstab.learning.data,
    graspstab.evaluation.tested_run), as named inputs: the index, the memory-mapped windows, the
    training-split statistics and the observation periods' motion (for the still-now split; it
    changes only with the labelling, as the windows do)."""
    return {
        "index": f"{directory}/index.parquet",
        "windows": f"{directory}/windows.npy",
        "normalisation": f"{directory}/normalisation.json",
        "motion": f"{directory}/motion.npy",
    }


def sweep_dataset(ms):
    """The same-end dataset of one sweep window, as :func:`dataset_inputs`."""
    return dataset_inputs(f"results/datasets/sweep/w{ms}ms")


def tuned_best(model):
    """The tuned spec of a family when the studies use tuned configurations, else nothing."""
    if config["sweep"]["configuration"] == "tuned":
        return {"best": f"results/tune/{model}/best.json"}
    return {}


def reference_spec(model):
    """The study spec of a family when the studies do not use tuning (3.4.3)."""
    if config["sweep"]["configuration"] == "tuned":
        return None
    return config["sweep"]["models"][model]


@functools.cache
def assignments():
    """The split study's object-to-split assignments (4.4), drawn when a job needs them, so a run
    that targets, say, one object's preprocessing does not need a complete split."""
    try:
        return sample_assignments(
            object_splits(), config["splits"]["count"], config["splits"]["sample_seed"]
        )
    except ValueError as exc:
        raise WorkflowError(
            f"graspstab configuration error: {exc}; the run's objects and splits are "
            f"{object_splits()} (objects.items.<id>.split). Give at least one object each split, "
            "or target outputs that do not need the learning studies."
        ) from None


def run_outputs(root, checkpoint=True):
    files = dict(RUN_FILES, **({"checkpoint": "model.pt"} if checkpoint else {}))
    return {k: f"{root}/{v}" for k, v in files.items()}


def baseline_runs(name, seeds=None, root="results"):
    return expand(
        f"{root}/train/baseline/{{model}}/seed{{seed}}/{{name}}",
        model=MODELS,
        seed=seeds or config["train"]["seeds"],
        name=name,
    )


def sweep_runs(name, seeds=None, root="results", windows_ms=None):
    return expand(
        f"{root}/train/sweep/{{model}}/w{{ms}}ms/seed{{seed}}/{{name}}",
        model=MODELS,
        ms=windows_ms or sweep_ms(),
        seed=seeds or config["sweep"]["seeds"],
        name=name,
    )


def split_runs():
    return expand(
        "results/train/splits/{model}/a{k}/seed{seed}/metrics.json",
        model=config["splits"]["family"],
        k=range(len(assignments())),
        seed=config["splits"]["seeds"],
    )
