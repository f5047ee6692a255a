# Marker ranking by QR with column pivoting (Lucero & Munhall 2008, Figs. 2-3, Table I).
# Each rule runs over all datasets in one job (params.datasets; one file per dataset in every
# named input and output, in that order): a job is mostly start-up, and a setting is read by
# every dataset alike, so changing it reruns exactly the outputs that depend on it.


rule rank_markers:
    input:
        npz=expand("<results>/{dataset}/data/displacements.npz", dataset=DATASETS),
        sentences=expand("<results>/{dataset}/data/sentences.tsv", dataset=DATASETS),
    output:
        r_values=expand("<results>/{dataset}/qr/r_values.tsv", dataset=DATASETS),
        r_values_meta=expand(
            "<results>/{dataset}/qr/r_values.meta.json", dataset=DATASETS
        ),
        r_values_top=expand("<results>/{dataset}/qr/r_values_top.tsv", dataset=DATASETS),
        r_values_top_meta=expand(
            "<results>/{dataset}/qr/r_values_top.meta.json", dataset=DATASETS
        ),
        rank=expand("<results>/{dataset}/qr/rank.tsv", dataset=DATASETS),
        rank_meta=expand("<results>/{dataset}/qr/rank.meta.json", dataset=DATASETS),
        png=[
            report(
                f"<results>/{d}/qr/r_values_plot.png",
                caption="../report/r_values.rst",
                category="2. Rank",
                subcategory=d,
            )
            for d in DATASETS
        ],
        more=figs_more("<results>/{dataset}/qr/r_values_plot", DATASETS),
        fig_meta=expand(
            "<results>/{dataset}/qr/r_values_plot.meta.json", dataset=DATASETS
        ),
        # across datasets (Table I, epsilon-ranks, Fig. 2 overlaid; drawn by the same job)
        across_table="<results>/tables/selected_markers.tsv",
        across_meta="<results>/tables/selected_markers.meta.json",
        across_sel_png=report(
            "<results>/figures/selected_markers.png",
            caption="../report/selected_markers.rst",
            category="0. Summary",
        ),
        across_sel_more=fig_more("<results>/figures/selected_markers"),
        across_sel_meta="<results>/figures/selected_markers.meta.json",
        across_summary="<results>/tables/rank_summary.tsv",
        across_summary_meta="<results>/tables/rank_summary.meta.json",
        across_png=report(
            "<results>/figures/r_values.png",
            caption="../report/r_values_all.rst",
            category="0. Summary",
        ),
        across_more=fig_more("<results>/figures/r_values"),
        across_fig_meta="<results>/figures/r_values.meta.json",
    log:
        "<results>/logs/rank_markers.log",
    benchmark:
        "<results>/benchmarks/rank_markers/all.tsv"
    priority: 12
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=10 + 2 * len(DATASETS),
    params:
        datasets=list(DATASETS),
        per_dataset=dataset_labels(DATASETS),
        method=config["qr"]["method"],
        k_max=config["qr"]["k_max"],
        top_n=config["qr"]["top_n"],
        route_check=config["qr"]["route_check"],
        tolerances_mm=config["qr"]["tolerances_mm"],
        r_normalisation=config["qr"]["r_normalisation"],
        across_orders=config["qr"]["table_orders"],
    message:
        "rank_markers ({n} datasets): QR with column pivoting, epsilon-rank (L&M Fig. 2, Table I)".format(
            n=len(DATASETS)
        )
    script:
        "../../scripts/rank_markers.py"


rule find_redundant_markers:
    input:
        npz=expand("<results>/{dataset}/data/displacements.npz", dataset=DATASETS),
    output:
        table=expand("<results>/{dataset}/qr/redundancy.tsv", dataset=DATASETS),
        meta=expand("<results>/{dataset}/qr/redundancy.meta.json", dataset=DATASETS),
        top=expand("<results>/{dataset}/qr/redundancy_top.tsv", dataset=DATASETS),
        top_meta=expand(
            "<results>/{dataset}/qr/redundancy_top.meta.json", dataset=DATASETS
        ),
    log:
        "<results>/logs/find_redundant_markers.log",
    benchmark:
        "<results>/benchmarks/find_redundant_markers/all.tsv"
    priority: 5
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=10 + 2 * len(DATASETS),
    params:
        datasets=list(DATASETS),
        noise_mm=config["qr"]["noise_mm"],
        min_copy_s=config["qr"]["min_copy_s"],
        top_n=config["qr"]["top_n"],
    message:
        "find_redundant_markers ({n} datasets): markers that copy others".format(
            n=len(DATASETS)
        )
    script:
        "../../scripts/find_redundant_markers.py"


rule sweep_sentences:
    input:
        npz=expand("<results>/{dataset}/data/displacements.npz", dataset=DATASETS),
        sentences=expand("<results>/{dataset}/data/sentences.tsv", dataset=DATASETS),
    output:
        sweep=expand("<results>/{dataset}/qr/sentence_sweep.tsv", dataset=DATASETS),
        sweep_meta=expand(
            "<results>/{dataset}/qr/sentence_sweep.meta.json", dataset=DATASETS
        ),
        stability=expand("<results>/{dataset}/qr/stability.tsv", dataset=DATASETS),
        stability_meta=expand(
            "<results>/{dataset}/qr/stability.meta.json", dataset=DATASETS
        ),
        agreement=expand(
            "<results>/{dataset}/qr/stability_agreement.tsv", dataset=DATASETS
        ),
        agreement_meta=expand(
            "<results>/{dataset}/qr/stability_agreement.meta.json", dataset=DATASETS
        ),
        png=[
            report(
                f"<results>/{d}/qr/sentence_sweep_plot.png",
                caption="../report/sentence_sweep.rst",
                category="2. Rank",
                subcategory=d,
            )
            for d in DATASETS
        ],
        more=figs_more("<results>/{dataset}/qr/sentence_sweep_plot", DATASETS),
        fig_meta=expand(
            "<results>/{dataset}/qr/sentence_sweep_plot.meta.json", dataset=DATASETS
        ),
    log:
        "<results>/logs/sweep_sentences.log",
    benchmark:
        "<results>/benchmarks/sweep_sentences/all.tsv"
    priority: 15
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=10 + 5 * len(DATASETS),
    params:
        datasets=list(DATASETS),
        per_dataset=dataset_labels(DATASETS),
        n_pivots=config["qr"]["sweep_pivots"],
        settle_tolerance=config["qr"]["settle_tolerance"],
        agreement_k=config["qr"]["agreement_k"],
        replicates=config["qr"]["replicates"],
        seed=config["qr"]["seed"],
    message:
        "sweep_sentences ({n} datasets): R against the number of sentences (L&M Fig. 3)".format(
            n=len(DATASETS)
        )
    script:
        "../../scripts/sweep_sentences.py"


rule compare_subsets:
    input:
        npz=expand("<results>/{dataset}/data/displacements.npz", dataset=DATASETS),
        sentences=expand("<results>/{dataset}/data/sentences.tsv", dataset=DATASETS),
    output:
        table=expand("<results>/{dataset}/qr/optimality.tsv", dataset=DATASETS),
        meta=expand("<results>/{dataset}/qr/optimality.meta.json", dataset=DATASETS),
    log:
        "<results>/logs/compare_subsets.log",
    benchmark:
        "<results>/benchmarks/compare_subsets/all.tsv"
    priority: 11
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=10 + 5 * len(DATASETS),
    params:
        datasets=list(DATASETS),
        k_max=config["qr"]["optimality_k_max"],
    message:
        "compare_subsets ({n} datasets): QR subset against exhaustive and greedy".format(
            n=len(DATASETS)
        )
    script:
        "../../scripts/compare_subsets.py"
