# Animation of held-out sentences driven by the k main markers (Fig. 8).
# One job over all datasets with held-out sentences (as the rules of qr.smk).


rule animate_heldout:
    input:
        npz=expand("<results>/{dataset}/data/displacements.npz", dataset=EVAL_DATASETS),
        sentences=expand(
            "<results>/{dataset}/data/sentences.tsv", dataset=EVAL_DATASETS
        ),
    output:
        anim=expand(
            f"<results>/{{dataset}}/anim/heldout.{config['animation']['format']}",
            dataset=EVAL_DATASETS,
        ),
        anim_meta=expand(
            "<results>/{dataset}/anim/heldout.meta.json", dataset=EVAL_DATASETS
        ),
        page=[
            report(
                f"<results>/{d}/anim/heldout_page.html",
                caption="../report/animation_page.rst",
                category="5. Animation",
                subcategory=d,
            )
            for d in EVAL_DATASETS
        ],
        page_meta=expand(
            "<results>/{dataset}/anim/heldout_page.meta.json", dataset=EVAL_DATASETS
        ),
        png=[
            report(
                f"<results>/{d}/anim/heldout_still.png",
                caption="../report/animation.rst",
                category="5. Animation",
                subcategory=d,
            )
            for d in EVAL_DATASETS
        ],
        more=figs_more("<results>/{dataset}/anim/heldout_still", EVAL_DATASETS),
        fig_meta=expand(
            "<results>/{dataset}/anim/heldout_still.meta.json", dataset=EVAL_DATASETS
        ),
    log:
        "<results>/logs/animate_heldout.log",
    benchmark:
        "<results>/benchmarks/animate_heldout/all.tsv"
    priority: 30
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=10 + 10 * len(EVAL_DATASETS),
    params:
        datasets=EVAL_DATASETS,
        per_dataset=dataset_labels(EVAL_DATASETS),
        method=config["qr"]["method"],
        k_max=config["qr"]["k_max"],
        animation=config["animation"],
    message:
        f"animate_heldout ({len(EVAL_DATASETS)} datasets): face driven by the k main markers (L&M Fig. 8)"
    script:
        "../../scripts/animate_heldout.py"
