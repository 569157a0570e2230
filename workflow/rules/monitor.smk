# Grasp-level warnings (our extension, docs/extensions.md "Streaming monitor and grasp-level warnings"): the trained models exported for
# deployment (TorchScript, ONNX, constants beside), and a streaming monitor of each family and of
# the friction-ratio proxy run over every validation and test replay, scored grasp by grasp.

MONITOR_MS = ms_of(config["monitor"]["window_s"])
EXPORT_FILES = {"onnx": "model.onnx", "torchscript": "model.torchscript.pt",
                "constants": "constants.json"}  # fmt: skip


rule export_monitor:
    input:
        checkpoint=f"results/train/baseline/{{model}}/seed{config['train']['seeds'][0]}/model.pt",
        metrics=f"results/train/baseline/{{model}}/seed{config['train']['seeds'][0]}/metrics.json",
    output:
        **{k: f"results/monitor/export/baseline_{{model}}/{v}" for k, v in EXPORT_FILES.items()},
    params:
        onnx_exporter=config["monitor"]["onnx_exporter"],
    threads: 1
    resources:
        mem_mb=2000,
        runtime=20,
    log:
        "results/logs/export_monitor/baseline_{model}.log",
    benchmark:
        "results/benchmarks/export_monitor/baseline_{model}.tsv"
    script:
        "../scripts/export_monitor.py"


rule export_pick:
    input:
        sweep=rules.aggregate_sweep.output.overview,
        **{f"checkpoint_{m}_w{ms}ms": sweep_first_seed(m, ms, "model.pt")
           for m in MODELS for ms in sweep_ms()},
        **{f"metrics_{m}_w{ms}ms": sweep_first_seed(m, ms, "metrics.json")
           for m in MODELS for ms in sweep_ms()},
    output:
        **{k: f"results/monitor/export/pick/{v}" for k, v in EXPORT_FILES.items()},
    params:
        onnx_exporter=config["monitor"]["onnx_exporter"],
    threads: 1
    resources:
        mem_mb=2000,
        runtime=20,
    log:
        "results/logs/export_pick/pick.log",
    benchmark:
        "results/benchmarks/export_pick/pick.tsv"
    script:
        "../scripts/export_monitor.py"


rule evaluate_monitor:
    input:
        tables=held_out_replays("replays"),
        traces=held_out_replays("traces"),
        **sweep_dataset(MONITOR_MS),
        **{f"checkpoint_{m}": sweep_first_seed(m, MONITOR_MS, "model.pt") for m in MODELS},
        **{f"metrics_{m}": sweep_first_seed(m, MONITOR_MS, "metrics.json") for m in MODELS},
    output:
        episodes="results/monitor/episodes.parquet",
        summary="results/monitor/summary.json",
        timeline="results/monitor/timeline.npz",
    params:
        splits=object_splits(),
        labels=config["labels"],
        dt=config["replay"]["timestep"],
        monitor=config["monitor"],
        threshold=config["train"]["threshold"],
    threads: 1
    resources:
        mem_mb=3000,
        runtime=60,
    log:
        "results/logs/evaluate_monitor/monitor.log",
    benchmark:
        "results/benchmarks/evaluate_monitor/monitor.tsv"
    script:
        "../scripts/evaluate_monitor.py"


rule plot_monitor:
    input:
        **dict(rules.evaluate_monitor.output.items()),
    output:
        leads="results/figures/monitor/lead_times.png",
        timeline="results/figures/monitor/timeline.png",
    params:
        dpi=config["report"]["figure_dpi"],
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    log:
        "results/logs/plot_monitor/monitor.log",
    benchmark:
        "results/benchmarks/plot_monitor/monitor.tsv"
    script:
        "../scripts/plot_monitor.py"


# What the report reads of this stage (named monitor_<artefact> there): the grasp-level summary,
# both figures, and every exported file (it lists each, with its constants).
MONITOR_ARTEFACTS = {
    "summary": rules.evaluate_monitor.output.summary,
    "leads_figure": rules.plot_monitor.output.leads,
    "timeline_figure": rules.plot_monitor.output.timeline,
    **{
        f"export_{name}_{k}": f"results/monitor/export/{name}/{v}"
        for name in [f"baseline_{m}" for m in MODELS] + ["pick"]
        for k, v in EXPORT_FILES.items()
    },
}
