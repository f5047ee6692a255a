# The lip model trained from data (Basu & Pentland 1997): FEM thin shell, minimal-force
# fitting, learned modes and partial-view reconstruction (Table 1).


rule simulate_lip_talker:
    output:
        tracks="<results>/lips/{lip_subject}/tracks.trc",
        truth="<results>/lips/{lip_subject}/truth.npz",
        truth_meta="<results>/lips/{lip_subject}/truth.meta.json",
    log:
        "<results>/logs/simulate_lip_talker/{lip_subject}.log",
    benchmark:
        "<results>/benchmarks/simulate_lip_talker/{lip_subject}.tsv"
    priority: 9
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
        mesh_png=report(
            "<results>/lips/{lip_subject}/mesh.png",
            caption="../report/lip_mesh.rst",
            category="6. Lip model",
            subcategory="{lip_subject}",
        ),
        mesh_more=fig_more("<results>/lips/{lip_subject}/mesh"),
        mesh_meta="<results>/lips/{lip_subject}/mesh.meta.json",
        modes="<results>/lips/{lip_subject}/modes.tsv",
        modes_meta="<results>/lips/{lip_subject}/modes.meta.json",
        modes_png=report(
            "<results>/lips/{lip_subject}/modes_plot.png",
            caption="../report/lip_modes.rst",
            category="6. Lip model",
            subcategory="{lip_subject}",
        ),
        modes_more=fig_more("<results>/lips/{lip_subject}/modes_plot"),
        modes_fig_meta="<results>/lips/{lip_subject}/modes_plot.meta.json",
        residuals="<results>/lips/{lip_subject}/fit_residuals.tsv",
        residuals_meta="<results>/lips/{lip_subject}/fit_residuals.meta.json",
        reconstruction=report(
            "<results>/lips/{lip_subject}/reconstruction.tsv",
            caption="../report/lip_reconstruction.rst",
            category="6. Lip model",
            subcategory="{lip_subject}",
        ),
        reconstruction_meta="<results>/lips/{lip_subject}/reconstruction.meta.json",
        counts=report(
            "<results>/lips/{lip_subject}/model_counts.tsv",
            caption="../report/lip_model_counts.rst",
            category="6. Lip model",
            subcategory="{lip_subject}",
        ),
        counts_meta="<results>/lips/{lip_subject}/model_counts.meta.json",
        sensitivity="<results>/lips/{lip_subject}/noise_sensitivity.tsv",
        sensitivity_meta="<results>/lips/{lip_subject}/noise_sensitivity.meta.json",
        heldout="<results>/lips/{lip_subject}/heldout_points.tsv",
        heldout_meta="<results>/lips/{lip_subject}/heldout_points.meta.json",
    log:
        "<results>/logs/fit_lip_model/{lip_subject}.log",
    benchmark:
        "<results>/benchmarks/fit_lip_model/{lip_subject}.tsv"
    priority: 8
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
