# Held-out evaluation: error against k (Figs. 9-10) and a measured-vs-model trajectory, one job
# per dataset with held-out sentences; the curves overlaid are an aggregation of their own.


rule evaluate_heldout:
    input:
        unpack(data),
    output:
        **table("curve", "<results>/{dataset}/eval/error_curve.tsv"),
        **figure(
            "png",
            "<results>/{dataset}/eval/error_curve_plot",
            caption="error_curve",
            category="4. Held-out error",
            subcategory="{dataset}",
        ),
        **table("traj", "<results>/{dataset}/eval/trajectory_errors.tsv"),
        **figure(
            "traj_png",
            "<results>/{dataset}/eval/trajectory",
            caption="trajectory",
            category="4. Held-out error",
            subcategory="{dataset}",
        ),
    log:
        "<results>/logs/evaluate_heldout/{dataset}.log",
    benchmark:
        "<results>/benchmarks/evaluate_heldout/{dataset}.tsv"
    priority: 20
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=10,
    params:
        label=dataset_label,
        method=config["qr"]["method"],
        k_max=config["qr"]["k_max"],
        marker=config["eval"]["trajectory_marker"],
        sentence=config["eval"]["trajectory_sentence"],
        k=config["eval"]["trajectory_k"],
    message:
        "evaluate_heldout {wildcards.dataset}: held-out error against k (L&M Figs. 9-10)"
    script:
        "../../scripts/evaluate_heldout.py"


rule summarise_heldout:
    input:
        curves=per_dataset("<results>/{dataset}/eval/error_curve.tsv", EVAL_DATASETS),
    output:
        **figure(
            "png",
            "<results>/figures/error_curves",
            caption="error_curves_all",
            category="0. Summary",
        ),
    log:
        "<results>/logs/summarise_heldout.log",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=5,
    params:
        labels=[DATASETS[d].label for d in EVAL_DATASETS],
    message:
        "summarise_heldout: the held-out error curves of all datasets (L&M Fig. 10)"
    script:
        "../../scripts/summarise_heldout.py"
