# Tables and figures across datasets (Table I, Figs. 2, 9-10 overlaid).


rule tabulate_selection:
    input:
        r_values=expand("<results>/{dataset}/qr/r_values.tsv", dataset=DATASETS),
        rank=expand("<results>/{dataset}/qr/rank.tsv", dataset=DATASETS),
    output:
        table="<results>/tables/selected_markers.tsv",
        meta="<results>/tables/selected_markers.meta.json",
        sel_png=report(
            "<results>/figures/selected_markers.png",
            caption="../report/selected_markers.rst",
            category="0. Summary",
        ),
        sel_more=fig_more("<results>/figures/selected_markers"),
        sel_meta="<results>/figures/selected_markers.meta.json",
        summary="<results>/tables/rank_summary.tsv",
        summary_meta="<results>/tables/rank_summary.meta.json",
        png=report(
            "<results>/figures/r_values.png",
            caption="../report/r_values_all.rst",
            category="0. Summary",
        ),
        more=fig_more("<results>/figures/r_values"),
        fig_meta="<results>/figures/r_values.meta.json",
    log:
        "<results>/logs/tabulate_selection.log",
    benchmark:
        "<results>/benchmarks/tabulate_selection/all.tsv"
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=5,
    params:
        labels=[DATASETS[d].label for d in DATASETS],
        orders=config["qr"]["table_orders"],
        tolerances_mm=config["qr"]["tolerances_mm"],
    message:
        "tabulate_selection: selected markers across datasets (L&M Table I)"
    script:
        "../../scripts/tabulate_selection.py"


rule plot_error_curves:
    input:
        curves=expand("<results>/{dataset}/eval/error_curve.tsv", dataset=EVAL_DATASETS),
    output:
        png=report(
            "<results>/figures/error_curves.png",
            caption="../report/error_curves_all.rst",
            category="0. Summary",
        ),
        more=fig_more("<results>/figures/error_curves"),
        fig_meta="<results>/figures/error_curves.meta.json",
    log:
        "<results>/logs/plot_error_curves.log",
    benchmark:
        "<results>/benchmarks/plot_error_curves/all.tsv"
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=5,
    params:
        labels=[DATASETS[d].label for d in EVAL_DATASETS],
    message:
        "plot_error_curves: held-out error curves overlaid"
    script:
        "../../scripts/plot_error_curves.py"


rule summarise_study:
    input:
        unpack(summary_inputs),
    output:
        summary="<results>/summary.txt",
        meta="<results>/summary.meta.json",
    log:
        "<results>/logs/summarise_study.log",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    params:
        study=STUDY,
        root=lambda wc, output: os.path.dirname(output.summary),
        lip_subjects=list(config["lips"]["subjects"]),
        skipped=SKIPPED,
    message:
        "summarise_study: the closing summary, {output.summary}"
    script:
        "../../scripts/summarise_study.py"


rule write_manifest:
    input:
        outputs=lambda wc: all_outputs(),
    output:
        manifest="<results>/manifest.tsv",
    log:
        "<results>/logs/write_manifest.log",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    params:
        root=lambda wc, output: os.path.dirname(output.manifest),
    message:
        "write_manifest: every output with its checksum, {output.manifest}"
    script:
        "../../scripts/write_manifest.py"
