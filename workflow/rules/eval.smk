# Held-out evaluation: error against k (Figs. 9-10) and a measured-vs-model trajectory.


rule evaluate_heldout:
    input:
        npz="<results>/{dataset}/data/displacements.npz",
        sentences="<results>/{dataset}/data/sentences.tsv",
    output:
        curve="<results>/{dataset}/eval/error_curve.tsv",
        curve_meta="<results>/{dataset}/eval/error_curve.meta.json",
        png=report(
            "<results>/{dataset}/eval/error_curve_plot.png",
            caption="../report/error_curve.rst",
            category="4. Held-out error",
            subcategory="{dataset}",
        ),
        more=fig_more("<results>/{dataset}/eval/error_curve_plot"),
        fig_meta="<results>/{dataset}/eval/error_curve_plot.meta.json",
        traj="<results>/{dataset}/eval/trajectory_errors.tsv",
        traj_meta="<results>/{dataset}/eval/trajectory_errors.meta.json",
        traj_png=report(
            "<results>/{dataset}/eval/trajectory.png",
            caption="../report/trajectory.rst",
            category="4. Held-out error",
            subcategory="{dataset}",
        ),
        traj_more=fig_more("<results>/{dataset}/eval/trajectory"),
        traj_fig_meta="<results>/{dataset}/eval/trajectory.meta.json",
    log:
        "<results>/logs/evaluate_heldout/{dataset}.log",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=10,
    params:
        label=lambda wc: DATASETS[wc.dataset].label,
        method=config["qr"]["method"],
        k_max=config["qr"]["k_max"],
        marker=config["eval"]["trajectory_marker"],
        sentence=config["eval"]["trajectory_sentence"],
        k=config["eval"]["trajectory_k"],
    message:
        "evaluate_heldout {wildcards.dataset}: held-out error against k (L&M Figs. 9-10)"
    script:
        "../../scripts/evaluate_heldout.py"
