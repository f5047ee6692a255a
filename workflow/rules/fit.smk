# Prediction of the secondary markers, X = R11^-1 R12, and the kinematic-region maps (Figs. 4-7).


rule fit_regions:
    input:
        unpack(data),
        mesh=dataset_mesh,
    output:
        **table("table", "<results>/{dataset}/fit/coefficients_k{k}.tsv"),
        **figure(
            "png",
            "<results>/{dataset}/fit/regions_k{k}",
            caption="regions",
            category="3. Regions",
            subcategory="{dataset}",
        ),
        **figure(
            "orth_png",
            "<results>/{dataset}/fit/orthogonal_k{k}",
            caption="orthogonal",
            category="3. Regions",
            subcategory="{dataset}",
        ),
    log:
        "<results>/logs/fit_regions/{dataset}_k{k}.log",
    benchmark:
        "<results>/benchmarks/fit_regions/{dataset}_k{k}.tsv"
    priority: 25
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=10,
    params:
        label=dataset_label,
        mesh_labels=dataset_mesh_labels,
        method=config["qr"]["method"],
        k_max=config["qr"]["k_max"],
        grid_n=config["fit"]["grid_n"],
        orthogonal_maps=config["fit"]["orthogonal_maps"],
    message:
        "fit_regions {wildcards.dataset} k={wildcards.k}: X = R11^-1 R12, region maps (L&M Figs. 4-7)"
    script:
        "../../scripts/fit_regions.py"
