# The papers' quantitative statements beside ours (results/<study>/tables/paper_comparison.tsv).


rule compare_with_papers:
    input:
        unpack(comparison_inputs),
    output:
        table="<results>/tables/paper_comparison.tsv",
        meta="<results>/tables/paper_comparison.meta.json",
        png=report(
            "<results>/figures/paper_comparison.png",
            caption="../report/paper_comparison.rst",
            category="0. Summary",
        ),
        more=fig_more("<results>/figures/paper_comparison"),
        fig_meta="<results>/figures/paper_comparison.meta.json",
    log:
        "<results>/logs/compare_with_papers.log",
    priority: 50
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=5,
    params:
        datasets=COMPARISON_DATASETS,
        lip_subject=COMPARISON_LIP_SUBJECT,
        tolerance_mm=0.5,
        r_normalisation=config["qr"]["r_normalisation"],
    message:
        "compare_with_papers: both papers' quantitative statements beside ours"
    script:
        "../../scripts/compare_with_papers.py"
