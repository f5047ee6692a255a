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
            category="5. Marker-set design",
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
        level=config["eval"]["interval_level"],
    message:
        "design_markers {wildcards.dataset}: the markers to place for the target error"
    script:
        "../../scripts/design_markers.py"
