# Parameter sweeps across datasets, and the sweep over virtual talkers.


rule run_sweep_point:
    input:
        npz="<results>/{dataset}/data/displacements.npz",
        sentences="<results>/{dataset}/data/sentences.tsv",
    output:
        table="<results>/sweeps/{sweep}/{dataset}/{point}.tsv",
        meta="<results>/sweeps/{sweep}/{dataset}/{point}.meta.json",
    log:
        "<results>/logs/run_sweep_point/{sweep}_{dataset}_{point}.log",
    benchmark:
        "<results>/benchmarks/run_sweep_point/{sweep}_{dataset}_{point}.tsv"
    wildcard_constraints:
        point=r"default|[A-Za-z_]+~[^/]+",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=10,
    params:
        point=lambda wc: SWEEPS[wc.sweep]["points"][wc.point],
        label=lambda wc: DATASETS[wc.dataset].label,
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
        table="<results>/tables/sweep_{sweep}.tsv",
        meta="<results>/tables/sweep_{sweep}.meta.json",
        png=report(
            "<results>/figures/sweep_{sweep}.png",
            caption="../report/sweep.rst",
            category="0. Summary",
        ),
        more=fig_more("<results>/figures/sweep_{sweep}"),
        fig_meta="<results>/figures/sweep_{sweep}.meta.json",
    log:
        "<results>/logs/summarise_sweep/{sweep}.log",
    benchmark:
        "<results>/benchmarks/summarise_sweep/{sweep}.tsv"
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
        r_values=expand("<results>/{dataset}/qr/r_values.tsv", dataset=TALKERS),
        curves=expand("<results>/{dataset}/eval/error_curve.tsv", dataset=TALKERS),
    output:
        table="<results>/tables/talkers.tsv",
        meta="<results>/tables/talkers.meta.json",
        freq="<results>/tables/talkers_top10.tsv",
        freq_meta="<results>/tables/talkers_top10.meta.json",
        png=report(
            "<results>/figures/talkers.png",
            caption="../report/talkers.rst",
            category="0. Summary",
        ),
        more=fig_more("<results>/figures/talkers"),
        fig_meta="<results>/figures/talkers.meta.json",
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
