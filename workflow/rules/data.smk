# Loading: readers, head-motion removal, gap check and filling, the displacement matrix A.
# One job over all datasets, grouped by subject (LOAD_ORDER): a subject's takes are read once
# for all its datasets, and the job's start-up is paid once; with several threads, subjects are
# loaded side by side in forked worker processes. Every dataset reruns when one changes, as
# every analysis rule after it does anyway.


rule load_dataset:
    input:
        data=list(
            dict.fromkeys(
                f for d in LOAD_ORDER for f in load_inputs(SimpleNamespace(dataset=d))
            )
        ),
    output:
        npz=expand("<results>/{dataset}/data/displacements.npz", dataset=LOAD_ORDER),
        npz_meta=expand(
            "<results>/{dataset}/data/displacements.meta.json", dataset=LOAD_ORDER
        ),
        gaps=expand("<results>/{dataset}/data/gap_report.tsv", dataset=LOAD_ORDER),
        gaps_meta=expand(
            "<results>/{dataset}/data/gap_report.meta.json", dataset=LOAD_ORDER
        ),
        sentences=expand("<results>/{dataset}/data/sentences.tsv", dataset=LOAD_ORDER),
        sentences_meta=expand(
            "<results>/{dataset}/data/sentences.meta.json", dataset=LOAD_ORDER
        ),
        gap_png=[
            report(
                f"<results>/{d}/data/gaps.png",
                caption="../report/gaps.rst",
                category="1. Data",
                subcategory=d,
            )
            for d in LOAD_ORDER
        ],
        gap_more=figs_more("<results>/{dataset}/data/gaps", LOAD_ORDER),
        gap_fig_meta=expand(
            "<results>/{dataset}/data/gaps.meta.json", dataset=LOAD_ORDER
        ),
    log:
        "<results>/logs/load_dataset.log",
    benchmark:
        "<results>/benchmarks/load_dataset/all.tsv"
    priority: 40
    conda:
        "../envs/facemotion.yaml"
    threads: LOAD_THREADS
    resources:
        mem_mb=4000 * LOAD_THREADS,
        runtime=20 * len(LOAD_ORDER),
    params:
        datasets=LOAD_ORDER,
        per_dataset={
            d: {
                "ds": dataset_params(d),
                "recordings": SUBJECTS[DATASETS[d].subject].recordings,
                "inputs": {"data": load_inputs(SimpleNamespace(dataset=d))},
            }
            for d in LOAD_ORDER
        },
        gaps=config["gaps"],
        checks=config["checks"],
        neutral=config["neutral"],
    message:
        f"load_dataset ({len(LOAD_ORDER)} datasets): files -> head-aligned, gap-filled displacement matrix A"
    script:
        "../../scripts/load_dataset.py"
