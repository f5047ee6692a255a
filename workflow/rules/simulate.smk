# Virtual subjects: the built-in default data, written as real C3D files (one per sentence).


rule simulate_subject:
    output:
        directory("<results>/virtual/{subject}"),
    log:
        "<results>/logs/simulate_subject/{subject}.log",
    benchmark:
        "<results>/benchmarks/simulate_subject/{subject}.tsv"
    priority: 50
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        sim=simulated_subject_params,
    message:
        "simulate_subject {wildcards.subject}: the virtual talker's C3D files"
    script:
        "../../scripts/simulate_subject.py"
