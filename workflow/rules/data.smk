# Loading: readers, head-motion removal, gap check and filling, the displacement matrix A.


rule load_dataset:
    input:
        load_inputs,
    output:
        npz="<results>/{dataset}/data/displacements.npz",
        npz_meta="<results>/{dataset}/data/displacements.meta.json",
        gaps="<results>/{dataset}/data/gap_report.tsv",
        gaps_meta="<results>/{dataset}/data/gap_report.meta.json",
        sentences="<results>/{dataset}/data/sentences.tsv",
        sentences_meta="<results>/{dataset}/data/sentences.meta.json",
        gap_png=report(
            "<results>/{dataset}/data/gaps.png",
            caption="../report/gaps.rst",
            category="1. Data",
            subcategory="{dataset}",
        ),
        gap_more=fig_more("<results>/{dataset}/data/gaps"),
        gap_fig_meta="<results>/{dataset}/data/gaps.meta.json",
    log:
        "<results>/logs/load_dataset/{dataset}.log",
    benchmark:
        "<results>/benchmarks/load_dataset/{dataset}.tsv"
    priority: 40
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=20,
    params:
        ds=lambda wc: dataset_params(wc.dataset),
        recordings=lambda wc: SUBJECTS[DATASETS[wc.dataset].subject].recordings,
        gaps=config["gaps"],
        checks=config["checks"],
        neutral=config["neutral"],
    message:
        "load_dataset {wildcards.dataset}: files -> head-aligned, gap-filled displacement matrix A"
    script:
        "../../scripts/load_dataset.py"
