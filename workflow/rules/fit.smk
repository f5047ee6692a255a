# Prediction of the secondary markers, X = R11^-1 R12, and the kinematic-region maps (Figs. 4-7).


rule fit_regions:
    input:
        npz="<results>/{dataset}/data/displacements.npz",
        sentences="<results>/{dataset}/data/sentences.tsv",
        mesh=dataset_mesh,
    output:
        table="<results>/{dataset}/fit/coefficients_k{k}.tsv",
        meta="<results>/{dataset}/fit/coefficients_k{k}.meta.json",
        png=report(
            "<results>/{dataset}/fit/regions_k{k}.png",
            caption="../report/regions.rst",
            category="3. Regions",
            subcategory="{dataset}",
        ),
        more=fig_more("<results>/{dataset}/fit/regions_k{k}"),
        fig_meta="<results>/{dataset}/fit/regions_k{k}.meta.json",
        orth_png=report(
            "<results>/{dataset}/fit/orthogonal_k{k}.png",
            caption="../report/orthogonal.rst",
            category="3. Regions",
            subcategory="{dataset}",
        ),
        orth_more=fig_more("<results>/{dataset}/fit/orthogonal_k{k}"),
        orth_meta="<results>/{dataset}/fit/orthogonal_k{k}.meta.json",
    log:
        "<results>/logs/fit_regions/{dataset}_k{k}.log",
    wildcard_constraints:
        k=r"\d+",
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
        grid_n=config["fit"]["grid_n"],
        orthogonal_maps=config["fit"]["orthogonal_maps"],
        mesh_labels=dataset_mesh_labels,
    message:
        "fit_regions {wildcards.dataset} k={wildcards.k}: X = R11^-1 R12, region maps (L&M Figs. 4-7)"
    script:
        "../../scripts/fit_regions.py"
