# Marker ranking by QR with column pivoting (Lucero & Munhall 2008, Figs. 2-3, Table I).


rule rank_markers:
    input:
        npz="<results>/{dataset}/data/displacements.npz",
        sentences="<results>/{dataset}/data/sentences.tsv",
    output:
        r_values="<results>/{dataset}/qr/r_values.tsv",
        r_values_meta="<results>/{dataset}/qr/r_values.meta.json",
        r_values_top="<results>/{dataset}/qr/r_values_top.tsv",
        r_values_top_meta="<results>/{dataset}/qr/r_values_top.meta.json",
        rank="<results>/{dataset}/qr/rank.tsv",
        rank_meta="<results>/{dataset}/qr/rank.meta.json",
        png=report(
            "<results>/{dataset}/qr/r_values_plot.png",
            caption="../report/r_values.rst",
            category="2. Rank",
            subcategory="{dataset}",
        ),
        more=fig_more("<results>/{dataset}/qr/r_values_plot"),
        fig_meta="<results>/{dataset}/qr/r_values_plot.meta.json",
    log:
        "<results>/logs/rank_markers/{dataset}.log",
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
        top_n=config["qr"]["top_n"],
        route_check=config["qr"]["route_check"],
        tolerances_mm=config["qr"]["tolerances_mm"],
        r_normalisation=config["qr"]["r_normalisation"],
    message:
        "rank_markers {wildcards.dataset}: QR with column pivoting, epsilon-rank (L&M Fig. 2)"
    script:
        "../../scripts/rank_markers.py"


rule find_redundant_markers:
    input:
        npz="<results>/{dataset}/data/displacements.npz",
    output:
        table="<results>/{dataset}/qr/redundancy.tsv",
        meta="<results>/{dataset}/qr/redundancy.meta.json",
        top="<results>/{dataset}/qr/redundancy_top.tsv",
        top_meta="<results>/{dataset}/qr/redundancy_top.meta.json",
    log:
        "<results>/logs/find_redundant_markers/{dataset}.log",
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
        npz="<results>/{dataset}/data/displacements.npz",
        sentences="<results>/{dataset}/data/sentences.tsv",
    output:
        sweep="<results>/{dataset}/qr/sentence_sweep.tsv",
        sweep_meta="<results>/{dataset}/qr/sentence_sweep.meta.json",
        stability="<results>/{dataset}/qr/stability.tsv",
        stability_meta="<results>/{dataset}/qr/stability.meta.json",
        agreement="<results>/{dataset}/qr/stability_agreement.tsv",
        agreement_meta="<results>/{dataset}/qr/stability_agreement.meta.json",
        png=report(
            "<results>/{dataset}/qr/sentence_sweep_plot.png",
            caption="../report/sentence_sweep.rst",
            category="2. Rank",
            subcategory="{dataset}",
        ),
        more=fig_more("<results>/{dataset}/qr/sentence_sweep_plot"),
        fig_meta="<results>/{dataset}/qr/sentence_sweep_plot.meta.json",
    log:
        "<results>/logs/sweep_sentences/{dataset}.log",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=20,
    params:
        label=lambda wc: DATASETS[wc.dataset].label,
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
        npz="<results>/{dataset}/data/displacements.npz",
        sentences="<results>/{dataset}/data/sentences.tsv",
    output:
        table="<results>/{dataset}/qr/optimality.tsv",
        meta="<results>/{dataset}/qr/optimality.meta.json",
    log:
        "<results>/logs/compare_subsets/{dataset}.log",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=30,
    params:
        k_max=config["qr"]["optimality_k_max"],
    message:
        "compare_subsets {wildcards.dataset}: QR subset against exhaustive and greedy"
    script:
        "../../scripts/compare_subsets.py"
