# Marker-set design (beyond the papers): which k markers to place for the target held-out
# error, from each dataset's sentences; one job per dataset (docs/design.md).


rule design_markers:
    input:
        unpack(data),
    output:
        **table("table", "<results>/{dataset}/design/markers.tsv"),
        **artifact("marker_set", "<results>/{dataset}/design/marker_set.json"),
        **artifact("protocol", "<results>/{dataset}/design/protocol.txt"),
        **figure(
            "png",
            "<results>/{dataset}/design/marker_set_plot",
            caption="marker_set",
            category="7. Marker-set design",
            subcategory="{dataset}",
        ),
    log:
        "<results>/logs/design_markers/{dataset}.log",
    benchmark:
        "<results>/benchmarks/design_markers/{dataset}.tsv"
    priority: 10
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=20,
    params:
        label=dataset_label,
        target_mm=config["eval"]["target_error_mm"],
        resamples=config["eval"]["interval_resamples"],
        selection_resamples=config["eval"]["selection_resamples"],
        level=config["eval"]["interval_level"],
    message:
        "design_markers {wildcards.dataset}: the markers to place for the target error"
    script:
        "../../scripts/design_markers.py"


rule render_face_page:
    input:
        npz=per_dataset("<results>/{dataset}/data/displacements.npz", DESIGN_DATASETS),
        coefficients=per_dataset(
            f"<results>/{{dataset}}/fit/coefficients_k{config['fit']['k'][0]}.tsv",
            DESIGN_DATASETS,
        ),
        r_values=per_dataset("<results>/{dataset}/qr/r_values.tsv", DESIGN_DATASETS),
        markers=per_dataset("<results>/{dataset}/design/markers.tsv", DESIGN_DATASETS),
        marker_set=per_dataset(
            "<results>/{dataset}/design/marker_set.json", DESIGN_DATASETS
        ),
    output:
        page=report(
            "<results>/figures/face_3d.html",
            caption="../report/face_3d.rst",
            category="0. Summary",
        ),
        page_meta=sidecar("<results>/figures/face_3d.html"),
    log:
        "<results>/logs/render_face_page.log",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=5,
    params:
        study=STUDY,
        labels=[DATASETS[d].label for d in DESIGN_DATASETS],
    message:
        "render_face_page: the study's interactive 3-D page, {output.page}"
    script:
        "../../scripts/render_face_page.py"


rule design_consensus:
    input:
        npz=lambda w: per_dataset(
            "<results>/{dataset}/data/displacements.npz", CONSENSUS.values()
        ),
        marker_sets=lambda w: per_dataset(
            "<results>/{dataset}/design/marker_set.json", CONSENSUS.values()
        ),
    output:
        **table("table", "<results>/design/consensus.tsv"),
        **table("subjects", "<results>/design/consensus_subjects.tsv"),
        **artifact("marker_set", "<results>/design/consensus_marker_set.json"),
        **figure(
            "png",
            "<results>/design/consensus_plot",
            caption="consensus",
            category="7. Marker-set design",
            subcategory="consensus",
        ),
    log:
        "<results>/logs/design_consensus.log",
    benchmark:
        "<results>/benchmarks/design_consensus.tsv"
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=30,
    params:
        subjects=lambda w: consensus_params(
            SUBJECTS, CONSENSUS, Path.cwd(), SHEET.parent, SHARED_DATA
        ),
        target_mm=config["eval"]["target_error_mm"],
        resamples=config["eval"]["interval_resamples"],
        selection_resamples=config["eval"]["selection_resamples"],
        level=config["eval"]["interval_level"],
    message:
        "design_consensus: one marker set for the study's subjects together"
    script:
        "../../scripts/design_consensus.py"
