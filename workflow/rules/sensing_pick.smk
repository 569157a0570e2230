# Sensor realism at the latency-aware window (sensing.pick_window): each family's sweep models at the
# streaming monitor's window (monitor.window_s, 4.5's pick, 0.01 s by default) scored under the same
# sensor conditions as the baseline models (sensing.smk). At 60 Hz a 0.01 s window holds less than
# one sensor sample, so this is where a sensor's rate should bite hardest.


rule evaluate_pick_robustness:
    input:
        **sweep_dataset(ms_of(config["monitor"]["window_s"])),
        traces=replay_outputs("traces"),
        checkpoints=pick_runs("model.pt"),
    output:
        runs="results/studies/sensing/pick/runs.parquet",
        summary="results/studies/sensing/pick/summary.json",
    params:
        trace_keys=replay_keys(),
        run_keys=[{"family": m, "seed": s, "training": "clean"} for m in MODELS
                  for s in pick_seeds()],
        sensing=config["sensing"],
        dt=config["replay"]["timestep"],
        seed=config["seed"],
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    log:
        "results/logs/evaluate_pick_robustness/pick.log",
    benchmark:
        "results/benchmarks/evaluate_pick_robustness/pick.tsv"
    script:
        "../scripts/evaluate_sensor_robustness.py"


SENSING_ARTEFACTS["pick_summary"] = rules.evaluate_pick_robustness.output.summary
