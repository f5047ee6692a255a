# Held-out evaluation: error against k (Figs. 9-10) and a measured-vs-model trajectory.
# One job over all datasets with held-out sentences (as the rules of qr.smk), which also draws
# their error curves overlaid.


rule evaluate_heldout:
    input:
        npz=expand("<results>/{dataset}/data/displacements.npz", dataset=EVAL_DATASETS),
        sentences=expand(
            "<results>/{dataset}/data/sentences.tsv", dataset=EVAL_DATASETS
        ),
    output:
        curve=expand("<results>/{dataset}/eval/error_curve.tsv", dataset=EVAL_DATASETS),
        curve_meta=expand(
            "<results>/{dataset}/eval/error_curve.meta.json", dataset=EVAL_DATASETS
        ),
        png=[
            report(
                f"<results>/{d}/eval/error_curve_plot.png",
                caption="../report/error_curve.rst",
                category="4. Held-out error",
                subcategory=d,
            )
            for d in EVAL_DATASETS
        ],
        more=figs_more("<results>/{dataset}/eval/error_curve_plot", EVAL_DATASETS),
        fig_meta=expand(
            "<results>/{dataset}/eval/error_curve_plot.meta.json",
            dataset=EVAL_DATASETS,
        ),
        traj=expand(
            "<results>/{dataset}/eval/trajectory_errors.tsv", dataset=EVAL_DATASETS
        ),
        traj_meta=expand(
            "<results>/{dataset}/eval/trajectory_errors.meta.json",
            dataset=EVAL_DATASETS,
        ),
        traj_png=[
            report(
                f"<results>/{d}/eval/trajectory.png",
                caption="../report/trajectory.rst",
                category="4. Held-out error",
                subcategory=d,
            )
            for d in EVAL_DATASETS
        ],
        traj_more=figs_more("<results>/{dataset}/eval/trajectory", EVAL_DATASETS),
        traj_fig_meta=expand(
            "<results>/{dataset}/eval/trajectory.meta.json", dataset=EVAL_DATASETS
        ),
        # across datasets: the error curves overlaid (drawn by the same job)
        across_png=report(
            "<results>/figures/error_curves.png",
            caption="../report/error_curves_all.rst",
            category="0. Summary",
        ),
        across_more=fig_more("<results>/figures/error_curves"),
        across_fig_meta="<results>/figures/error_curves.meta.json",
    log:
        "<results>/logs/evaluate_heldout.log",
    benchmark:
        "<results>/benchmarks/evaluate_heldout/all.tsv"
    priority: 20
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=10 + 2 * len(EVAL_DATASETS),
    params:
        datasets=EVAL_DATASETS,
        per_dataset=dataset_labels(EVAL_DATASETS),
        method=config["qr"]["method"],
        k_max=config["qr"]["k_max"],
        marker=config["eval"]["trajectory_marker"],
        sentence=config["eval"]["trajectory_sentence"],
        k=config["eval"]["trajectory_k"],
    message:
        "evaluate_heldout ({n} datasets): held-out error against k (L&M Figs. 9-10), overlaid".format(
            n=len(EVAL_DATASETS)
        )
    script:
        "../../scripts/evaluate_heldout.py"
