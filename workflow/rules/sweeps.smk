# Parameter sweeps across datasets (one job per sweep, dataset and point), and the sweep over
# virtual talkers.


rule run_sweep_point:
    input:
        unpack(data),
    output:
        **table("table", "<results>/sweeps/{sweep}/{dataset}/{point}.tsv"),
    log:
        "<results>/logs/run_sweep_point/{sweep}_{dataset}_{point}.log",
    benchmark:
        "<results>/benchmarks/run_sweep_point/{sweep}_{dataset}_{point}.tsv"
    wildcard_constraints:
        sweep=_choice(SWEEPS),
        point=r"default|[A-Za-z_]+~[^/]+",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=10,
    params:
        point=lambda wc: SWEEPS[wc.sweep]["points"][wc.point],
        label=dataset_label,
        method=config["qr"]["method"],
        settle_tolerance=config["qr"]["settle_tolerance"],
        r_normalisation=config["qr"]["r_normalisation"],
    message:
        "run_sweep_point {wildcards.sweep} {wildcards.dataset} {wildcards.point}"
    script:
        "../../scripts/run_sweep_point.py"


rule summarise_sweep:
    input:
        sweep_point_files,
    output:
        **table("table", "<results>/tables/sweep_{sweep}.tsv"),
        **figure(
            "png",
            "<results>/figures/sweep_{sweep}",
            caption="sweep",
            category="0. Summary",
        ),
    log:
        "<results>/logs/summarise_sweep/{sweep}.log",
    benchmark:
        "<results>/benchmarks/summarise_sweep/{sweep}.tsv"
    wildcard_constraints:
        sweep=_choice(SWEEPS),
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=5,
    message:
        "summarise_sweep {wildcards.sweep}"
    script:
        "../../scripts/summarise_sweep.py"


rule summarise_talkers:
    input:
        r_values=per_dataset("<results>/{dataset}/qr/r_values.tsv", TALKERS),
        curves=per_dataset("<results>/{dataset}/eval/error_curve.tsv", TALKERS),
    output:
        **tables("<results>/tables", "talkers", "talkers_top10"),
        **figure(
            "png",
            "<results>/figures/talkers",
            caption="talkers",
            category="0. Summary",
        ),
    log:
        "<results>/logs/summarise_talkers.log",
    benchmark:
        "<results>/benchmarks/summarise_talkers/all.tsv"
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=5,
    params:
        talkers=TALKERS,
    message:
        "summarise_talkers: first pivots across virtual talkers"
    script:
        "../../scripts/summarise_talkers.py"
