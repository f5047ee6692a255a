# The lip model trained from data (Basu & Pentland 1997): FEM thin shell, minimal-force
# fitting, learned modes and partial-view reconstruction (Table 1), one job per lip subject.


rule simulate_lip_talker:
    output:
        **artifact("truth", "<results>/lips/{lip_subject}/truth.npz"),
        tracks="<results>/lips/{lip_subject}/tracks.trc",
    log:
        "<results>/logs/simulate_lip_talker/{lip_subject}.log",
    benchmark:
        "<results>/benchmarks/simulate_lip_talker/{lip_subject}.tsv"
    priority: 14
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=5,
    params:
        lip=lip_params,
    message:
        "simulate_lip_talker {wildcards.lip_subject}: virtual lip tracks"
    script:
        "../../scripts/simulate_lip_talker.py"


rule fit_lip_model:
    input:
        unpack(lip_inputs),
    output:
        **figure(
            "mesh_png",
            "<results>/lips/{lip_subject}/mesh",
            caption="lip_mesh",
            category="6. Lip model",
            subcategory="{lip_subject}",
        ),
        **tables("<results>/lips/{lip_subject}", "modes", "fit_residuals"),
        **figure(
            "modes_png",
            "<results>/lips/{lip_subject}/modes_plot",
            caption="lip_modes",
            category="6. Lip model",
            subcategory="{lip_subject}",
        ),
        **reported_table(
            "reconstruction",
            "<results>/lips/{lip_subject}/reconstruction.tsv",
            caption="lip_reconstruction",
            category="6. Lip model",
            subcategory="{lip_subject}",
        ),
        **reported_table(
            "counts",
            "<results>/lips/{lip_subject}/model_counts.tsv",
            caption="lip_model_counts",
            category="6. Lip model",
            subcategory="{lip_subject}",
        ),
        **tables("<results>/lips/{lip_subject}", "noise_sensitivity", "heldout_points"),
    log:
        "<results>/logs/fit_lip_model/{lip_subject}.log",
    benchmark:
        "<results>/benchmarks/fit_lip_model/{lip_subject}.tsv"
    priority: 13
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=20,
    params:
        lip=lip_params,
    message:
        "fit_lip_model {wildcards.lip_subject}: FEM lip model, modes, LLSE (B&P Table 1)"
    script:
        "../../scripts/fit_lip_model.py"


rule reconstruct_lip_seed:
    output:
        **table("table", "<results>/lips/{lip_subject}/seeds/table1_seed{seed}.tsv"),
    log:
        "<results>/logs/reconstruct_lip_seed/{lip_subject}_seed{seed}.log",
    benchmark:
        "<results>/benchmarks/reconstruct_lip_seed/{lip_subject}_seed{seed}.tsv"
    wildcard_constraints:
        lip_subject=_choice(LIP_SEEDS),
        seed=r"\d+",
    priority: 12
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        lip=lip_params,
    message:
        "reconstruct_lip_seed {wildcards.lip_subject} seed {wildcards.seed}: B&P Table 1"
    script:
        "../../scripts/reconstruct_lip_seed.py"


rule summarise_lip_seeds:
    input:
        tables=lip_seed_tables,
    output:
        **reported_table(
            "table",
            "<results>/lips/table1_seeds.tsv",
            caption="lip_table1_seeds",
            category="6. Lip model",
        ),
    log:
        "<results>/logs/summarise_lip_seeds.log",
    priority: 12
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    message:
        "summarise_lip_seeds: B&P Table 1 over the virtual lip talker's seeds"
    script:
        "../../scripts/summarise_lip_seeds.py"
