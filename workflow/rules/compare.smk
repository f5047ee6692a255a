# The papers' quantitative statements beside ours (results/<study>/tables/paper_comparison.tsv).


rule compare_with_papers:
    input:
        unpack(comparison_inputs),
    output:
        **table("table", "<results>/tables/paper_comparison.tsv"),
        **figure(
            "png",
            "<results>/figures/paper_comparison",
            caption="paper_comparison",
            category="0. Summary",
        ),
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
        r_normalisation=config["qr"]["r_normalisation"],
    message:
        "compare_with_papers: both papers' quantitative statements beside ours"
    script:
        "../../scripts/compare_with_papers.py"
