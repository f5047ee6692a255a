# Virtual subjects: the built-in default data, written as real files (one per sentence).


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
        sim=lambda wc: simulation_params(SUBJECTS[wc.subject], SHARED_DATA),
    message:
        "simulate_subject {wildcards.subject}: the virtual talker's files"
    script:
        "../../scripts/simulate_subject.py"
