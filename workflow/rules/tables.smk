# The closing summary and the manifest.


rule summarise_study:
    input:
        unpack(summary_inputs),
    output:
        **artifact("summary", "<results>/summary.txt"),
    log:
        "<results>/logs/summarise_study.log",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    params:
        study=STUDY,
        root=lambda wc, output: os.path.dirname(output.summary),
        lip_subjects=LIP_SUBJECTS,
        skipped=SKIPPED,
        dataset_labels=[DATASETS[d].label for d in DATASETS],
        builtin_lips=builtin_lip_subjects(),
    message:
        "summarise_study: the closing summary, {output.summary}"
    script:
        "../../scripts/summarise_study.py"


rule write_manifest:
    input:
        outputs=lambda wc: all_outputs(),
    output:
        manifest="<results>/manifest.tsv",
    log:
        "<results>/logs/write_manifest.log",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    params:
        root=lambda wc, output: os.path.dirname(output.manifest),
    message:
        "write_manifest: every output with its checksum, {output.manifest}"
    script:
        "../../scripts/write_manifest.py"
