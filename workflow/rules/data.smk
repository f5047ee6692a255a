# Loading: readers, checks, head-motion removal, gap filling, the displacement matrix A.


rule load_dataset:
    input:
        data=load_inputs,
    output:
        **artifact("npz", "<results>/{dataset}/data/displacements.npz"),
        **tables("<results>/{dataset}/data", "gap_report", "sentences"),
        **figure(
            "gaps",
            "<results>/{dataset}/data/gaps",
            caption="gaps",
            category="1. Data",
            subcategory="{dataset}",
        ),
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
        ds=lambda wc: dataset_params(SUBJECTS, DATASETS, wc.dataset, RECORDED),
        recordings=lambda wc: [
            RECORDED.get(r, r)
            for r in SUBJECTS[DATASETS[wc.dataset].subject].recordings
        ],
        fingerprint=lambda wc: FINGERPRINTS.get(wc.dataset, []),
        files_at=load_files_at,
        gaps=config["gaps"],
        checks=config["checks"],
        neutral=config["neutral"],
        max_filled_fraction=config["qr"]["max_filled_fraction"],
    message:
        "load_dataset {wildcards.dataset}: files -> head-aligned, gap-filled displacement matrix A"
    script:
        "../../scripts/load_dataset.py"
