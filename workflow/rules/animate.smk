# Animation of held-out sentences driven by the k main markers (Fig. 8).


rule animate_heldout:
    input:
        npz="<results>/{dataset}/data/displacements.npz",
        sentences="<results>/{dataset}/data/sentences.tsv",
    output:
        anim=f"<results>/{{dataset}}/anim/heldout.{config['animation']['format']}",
        anim_meta="<results>/{dataset}/anim/heldout.meta.json",
        page=report(
            "<results>/{dataset}/anim/heldout_page.html",
            caption="../report/animation_page.rst",
            category="5. Animation",
            subcategory="{dataset}",
        ),
        page_meta="<results>/{dataset}/anim/heldout_page.meta.json",
        png=report(
            "<results>/{dataset}/anim/heldout_still.png",
            caption="../report/animation.rst",
            category="5. Animation",
            subcategory="{dataset}",
        ),
        more=fig_more("<results>/{dataset}/anim/heldout_still"),
        fig_meta="<results>/{dataset}/anim/heldout_still.meta.json",
    log:
        "<results>/logs/animate_heldout/{dataset}.log",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=20,
    params:
        label=lambda wc: DATASETS[wc.dataset].label,
        method=config["qr"]["method"],
        k_max=config["qr"]["k_max"],
        animation=config["animation"],
    message:
        "animate_heldout {wildcards.dataset}: face driven by the k main markers (L&M Fig. 8)"
    script:
        "../../scripts/animate_heldout.py"
