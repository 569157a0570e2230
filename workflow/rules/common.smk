# Configuration (Hydra compose + schema validation, once at load time) and input functions.

from pathlib import Path

from graspstab.config import ConfigError, load_config

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

# One conda environment for every rule (snakemake --sdm conda); path relative to workflow/rules/.
CONDA_ENV = "../../envs/graspstab.yaml"


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
    """What a shard's result depends on: everything in the synthesis group but the shard count
    (adding shards must not rerun the existing ones)."""
    return {k: v for k, v in config["synthesis"].items() if k != "shards"}


def shard_tables_of(objects):
    """Every shard table of the given objects."""
    return expand(
        "results/grasps/{object}/shard_{shard}.parquet",
        object=objects,
        shard=range(config["synthesis"]["shards"]),
    )


def shard_tables(wildcards):
    """All shard tables of one object."""
    return shard_tables_of([wildcards.object])


def grasp_outputs(name):
    """One synthesis artefact for every object of the run."""
    return expand("results/grasps/{object}/{name}", object=object_ids(), name=name)
