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


# One job for all lip subjects (each job costs about 2 s of start-up here), each subject on its
# own as in a job of its own (run_per_dataset: its inputs, outputs, params and sidecars).
rule fit_lip_model:
    input:
        tracks=[t for ls in LIP_SUBJECTS for t in lip_inputs(lip_wc(ls))["tracks"]],
        mesh=[m for ls in LIP_SUBJECTS for m in lip_inputs_lists(ls)["mesh"]],
    output:
        mesh_png=[
            report(
                f"<results>/lips/{ls}/mesh.png",
                caption="../report/lip_mesh.rst",
                category="6. Lip model",
                subcategory=ls,
            )
            for ls in LIP_SUBJECTS
        ],
        mesh_more=figs_more("<results>/lips/{dataset}/mesh", LIP_SUBJECTS),
        mesh_meta=expand("<results>/lips/{ls}/mesh.meta.json", ls=LIP_SUBJECTS),
        modes=expand("<results>/lips/{ls}/modes.tsv", ls=LIP_SUBJECTS),
        modes_meta=expand("<results>/lips/{ls}/modes.meta.json", ls=LIP_SUBJECTS),
        modes_png=[
            report(
                f"<results>/lips/{ls}/modes_plot.png",
                caption="../report/lip_modes.rst",
                category="6. Lip model",
                subcategory=ls,
            )
            for ls in LIP_SUBJECTS
        ],
        modes_more=figs_more("<results>/lips/{dataset}/modes_plot", LIP_SUBJECTS),
        modes_fig_meta=expand(
            "<results>/lips/{ls}/modes_plot.meta.json", ls=LIP_SUBJECTS
        ),
        residuals=expand("<results>/lips/{ls}/fit_residuals.tsv", ls=LIP_SUBJECTS),
        residuals_meta=expand(
            "<results>/lips/{ls}/fit_residuals.meta.json", ls=LIP_SUBJECTS
        ),
        reconstruction=[
            report(
                f"<results>/lips/{ls}/reconstruction.tsv",
                caption="../report/lip_reconstruction.rst",
                category="6. Lip model",
                subcategory=ls,
            )
            for ls in LIP_SUBJECTS
        ],
        reconstruction_meta=expand(
            "<results>/lips/{ls}/reconstruction.meta.json", ls=LIP_SUBJECTS
        ),
        counts=[
            report(
                f"<results>/lips/{ls}/model_counts.tsv",
                caption="../report/lip_model_counts.rst",
                category="6. Lip model",
                subcategory=ls,
            )
            for ls in LIP_SUBJECTS
        ],
        counts_meta=expand(
            "<results>/lips/{ls}/model_counts.meta.json", ls=LIP_SUBJECTS
        ),
        sensitivity=expand("<results>/lips/{ls}/noise_sensitivity.tsv", ls=LIP_SUBJECTS),
        sensitivity_meta=expand(
            "<results>/lips/{ls}/noise_sensitivity.meta.json", ls=LIP_SUBJECTS
        ),
        heldout=expand("<results>/lips/{ls}/heldout_points.tsv", ls=LIP_SUBJECTS),
        heldout_meta=expand(
            "<results>/lips/{ls}/heldout_points.meta.json", ls=LIP_SUBJECTS
        ),
    log:
        "<results>/logs/fit_lip_model.log",
    benchmark:
        "<results>/benchmarks/fit_lip_model/all.tsv"
    priority: 13
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=20,
    params:
        datasets=LIP_SUBJECTS,
        part_wildcard="lip_subject",
        per_dataset={
            ls: {"lip": lip_params(lip_wc(ls)), "inputs": lip_inputs_lists(ls)}
            for ls in LIP_SUBJECTS
        },
    message:
        f"fit_lip_model ({', '.join(LIP_SUBJECTS)}): FEM lip model, modes, LLSE (B&P Table 1)"
    script:
        "../../scripts/fit_lip_model.py"
