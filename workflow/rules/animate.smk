# Animation of held-out sentences driven by the k main markers (Fig. 8).


rule animate_heldout:
    input:
        unpack(data),
    output:
        **artifact(
            "anim",
            f"<results>/{{dataset}}/anim/heldout.{config['animation']['format']}",
        ),
        **figure(
            "png",
            "<results>/{dataset}/anim/heldout_still",
            caption="animation",
            category="5. Animation",
            subcategory="{dataset}",
        ),
        page=report(
            "<results>/{dataset}/anim/heldout_page.html",
            caption="../report/animation_page.rst",
            category="5. Animation",
            subcategory="{dataset}",
        ),
        page_meta=sidecar("<results>/{dataset}/anim/heldout_page.html"),
    log:
        "<results>/logs/animate_heldout/{dataset}.log",
    benchmark:
        "<results>/benchmarks/animate_heldout/{dataset}.tsv"
    priority: 30
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=20,
    params:
        label=dataset_label,
        method=config["qr"]["method"],
        k_max=config["qr"]["k_max"],
        animation=config["animation"],
    message:
        "animate_heldout {wildcards.dataset}: face driven by the k main markers (L&M Fig. 8)"
    script:
        "../../scripts/animate_heldout.py"
