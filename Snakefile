# graspstab: predicting grasp instability from fingertip forces.
# Thin on purpose: config loading and input functions live in workflow/rules/common.smk, each stage
# in its own rule file, all logic in src/graspstab. Run: snakemake --cores 2 results/report.html


include: "workflow/rules/common.smk"
include: "workflow/rules/assets.smk"
include: "workflow/rules/objects.smk"
include: "workflow/rules/hand.smk"
include: "workflow/rules/synthesis.smk"
include: "workflow/rules/replay.smk"
include: "workflow/rules/dataset.smk"
include: "workflow/rules/train.smk"
include: "workflow/rules/monitor.smk"


# The creep-free load-ramp benchmark beside the main run (docs/protocols.md "The creep-free load ramp"), when enabled.
if config["creep_free"]["enabled"]:

    include: "workflow/rules/creep_free.smk"


if config["sensing"]["robustness"]:

    include: "workflow/rules/sensing.smk"

    if config["sensing"]["pick_window"]:

        include: "workflow/rules/sensing_pick.smk"


if config["audit"]["enabled"]:

    include: "workflow/rules/audit.smk"


# Object-level k-fold cross-validation under each protocol (docs/results.md "Generalisation
# across objects"), when enabled.
if config["crossval"]["enabled"]:

    include: "workflow/rules/crossval.smk"


# The closed loop: a grip reflex driven by the monitor in the replay (docs/extensions.md "Closed
# loop"), when enabled on the fixed split or over the cross-validation folds.
if config["closed_loop"]["enabled"] or config["closed_loop"]["folds"]["enabled"]:

    include: "workflow/rules/closed_loop.smk"


include: "workflow/rules/report.smk"


rule all:
    default_target: True
    input:
        "results/report.html",
