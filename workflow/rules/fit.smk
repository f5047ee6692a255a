# Prediction of the secondary markers, X = R11^-1 R12, and the kinematic-region maps (Figs. 4-7).
# One job per k over all datasets (as the rules of qr.smk): a dataset's maps take a few seconds,
# a job's start-up about one more.


rule fit_regions:
    input:
        npz=expand("<results>/{dataset}/data/displacements.npz", dataset=DATASETS),
        sentences=expand("<results>/{dataset}/data/sentences.tsv", dataset=DATASETS),
        mesh=[m for d in DATASETS for m in dataset_mesh(SimpleNamespace(dataset=d))],
    output:
        table=expand(
            "<results>/{dataset}/fit/coefficients_k{{k}}.tsv", dataset=DATASETS
        ),
        meta=expand(
            "<results>/{dataset}/fit/coefficients_k{{k}}.meta.json", dataset=DATASETS
        ),
        png=[
            report(
                f"<results>/{d}/fit/regions_k{{k}}.png",
                caption="../report/regions.rst",
                category="3. Regions",
                subcategory=d,
            )
            for d in DATASETS
        ],
        more=figs_more("<results>/{dataset}/fit/regions_k{k}", DATASETS),
        fig_meta=expand(
            "<results>/{dataset}/fit/regions_k{{k}}.meta.json", dataset=DATASETS
        ),
        orth_png=[
            report(
                f"<results>/{d}/fit/orthogonal_k{{k}}.png",
                caption="../report/orthogonal.rst",
                category="3. Regions",
                subcategory=d,
            )
            for d in DATASETS
        ],
        orth_more=figs_more("<results>/{dataset}/fit/orthogonal_k{k}", DATASETS),
        orth_meta=expand(
            "<results>/{dataset}/fit/orthogonal_k{{k}}.meta.json", dataset=DATASETS
        ),
    log:
        "<results>/logs/fit_regions/k{k}.log",
    benchmark:
        "<results>/benchmarks/fit_regions/k{k}.tsv"
    wildcard_constraints:
        k=r"\d+",
    priority: 25
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=10 + 2 * len(DATASETS),
    params:
        datasets=list(DATASETS),
        per_dataset={
            d: {
                "label": DATASETS[d].label,
                "mesh_labels": dataset_mesh_labels(SimpleNamespace(dataset=d)),
                "inputs": {"mesh": dataset_mesh(SimpleNamespace(dataset=d))},
            }
            for d in DATASETS
        },
        method=config["qr"]["method"],
        k_max=config["qr"]["k_max"],
        grid_n=config["fit"]["grid_n"],
        orthogonal_maps=config["fit"]["orthogonal_maps"],
    message:
        f"fit_regions k={{wildcards.k}} ({len(DATASETS)} datasets): X = R11^-1 R12, region maps (L&M Figs. 4-7)"
    script:
        "../../scripts/fit_regions.py"
