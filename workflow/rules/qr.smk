# Marker ranking by QR with column pivoting (Lucero & Munhall 2008, Figs. 2-3, Table I), one
# job per dataset; the tables and figures across datasets are an aggregation of their own.


rule rank_markers:
    input:
        unpack(data),
        gap_report="<results>/{dataset}/data/gap_report.tsv",
    output:
        **tables("<results>/{dataset}/qr", "r_values", "r_values_top", "rank"),
        **figure(
            "png",
            "<results>/{dataset}/qr/r_values_plot",
            caption="r_values",
            category="2. Rank",
            subcategory="{dataset}",
        ),
    log:
        "<results>/logs/rank_markers/{dataset}.log",
    benchmark:
        "<results>/benchmarks/rank_markers/{dataset}.tsv"
    priority: 12
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
        top_n=config["qr"]["top_n"],
        route_check=config["qr"]["route_check"],
        tolerances_mm=config["qr"]["tolerances_mm"],
        r_normalisation=config["qr"]["r_normalisation"],
        target_mm=config["eval"]["target_error_mm"],
        resamples=config["eval"]["interval_resamples"],
        level=config["eval"]["interval_level"],
        flag_pivots=config["qr"]["flag_pivots"],
        flag_filled_fraction=config["qr"]["flag_filled_fraction"],
    message:
        "rank_markers {wildcards.dataset}: QR with column pivoting, epsilon-rank (L&M Fig. 2)"
    script:
        "../../scripts/rank_markers.py"


rule summarise_ranking:
    input:
        r_values=per_dataset("<results>/{dataset}/qr/r_values.tsv", DATASETS),
        rank=per_dataset("<results>/{dataset}/qr/rank.tsv", DATASETS),
    output:
        **tables("<results>/tables", "selected_markers", "rank_summary"),
        **figure(
            "selected_png",
            "<results>/figures/selected_markers",
            caption="selected_markers",
            category="0. Summary",
        ),
        **figure(
            "r_values_png",
            "<results>/figures/r_values",
            caption="r_values_all",
            category="0. Summary",
        ),
    log:
        "<results>/logs/summarise_ranking.log",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=5,
    params:
        labels=[DATASETS[d].label for d in DATASETS],
        table_orders=config["qr"]["table_orders"],
        tolerances_mm=config["qr"]["tolerances_mm"],
        flag_pivots=config["qr"]["flag_pivots"],
        flag_filled_fraction=config["qr"]["flag_filled_fraction"],
    message:
        "summarise_ranking: Table I, epsilon-ranks and Fig. 2 across datasets"
    script:
        "../../scripts/summarise_ranking.py"


rule find_redundant_markers:
    input:
        unpack(data),
    output:
        **tables("<results>/{dataset}/qr", "redundancy", "redundancy_top"),
    log:
        "<results>/logs/find_redundant_markers/{dataset}.log",
    benchmark:
        "<results>/benchmarks/find_redundant_markers/{dataset}.tsv"
    priority: 5
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=10,
    params:
        noise_mm=config["qr"]["noise_mm"],
        min_copy_s=config["qr"]["min_copy_s"],
        top_n=config["qr"]["top_n"],
    message:
        "find_redundant_markers {wildcards.dataset}: markers that copy others"
    script:
        "../../scripts/find_redundant_markers.py"


rule sweep_sentences:
    input:
        unpack(data),
    output:
        **tables(
            "<results>/{dataset}/qr",
            "sentence_sweep",
            "stability",
            "stability_agreement",
        ),
        **figure(
            "png",
            "<results>/{dataset}/qr/sentence_sweep_plot",
            caption="sentence_sweep",
            category="2. Rank",
            subcategory="{dataset}",
        ),
    log:
        "<results>/logs/sweep_sentences/{dataset}.log",
    benchmark:
        "<results>/benchmarks/sweep_sentences/{dataset}.tsv"
    priority: 15
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=10,
    params:
        label=dataset_label,
        n_pivots=config["qr"]["sweep_pivots"],
        settle_tolerance=config["qr"]["settle_tolerance"],
        agreement_k=config["qr"]["agreement_k"],
        replicates=config["qr"]["replicates"],
        seed=config["qr"]["seed"],
    message:
        "sweep_sentences {wildcards.dataset}: R against the number of sentences (L&M Fig. 3)"
    script:
        "../../scripts/sweep_sentences.py"


rule compare_subsets:
    input:
        unpack(data),
    output:
        **table("table", "<results>/{dataset}/qr/optimality.tsv"),
    log:
        "<results>/logs/compare_subsets/{dataset}.log",
    benchmark:
        "<results>/benchmarks/compare_subsets/{dataset}.tsv"
    priority: 11
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=10,
    params:
        k_max=config["qr"]["optimality_k_max"],
    message:
        "compare_subsets {wildcards.dataset}: QR subset against exhaustive and greedy"
    script:
        "../../scripts/compare_subsets.py"
