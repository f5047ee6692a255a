# Virtual subjects: the built-in default data, written as real C3D files (one per sentence).
# One job for all virtual subjects (VIRTUAL), as load_dataset loads them all in one job; with
# several threads, subjects are written side by side in forked worker processes.


if VIRTUAL:

    rule simulate_subject:
        output:
            dirs=[directory(f"<results>/virtual/{s}") for s in VIRTUAL],
        log:
            "<results>/logs/simulate_subject.log",
        benchmark:
            "<results>/benchmarks/simulate_subject/all.tsv"
        priority: 50
        conda:
            "../envs/facemotion.yaml"
        threads: min(4, len(VIRTUAL))
        resources:
            mem_mb=2000 * min(4, len(VIRTUAL)),
            runtime=10 * len(VIRTUAL),
        params:
            datasets=VIRTUAL,
            per_dataset={
                s: {"sim": simulated_subject_params(SimpleNamespace(subject=s))}
                for s in VIRTUAL
            },
        message:
            f"simulate_subject ({len(VIRTUAL)} subjects): the virtual talkers' C3D files"
        script:
            "../../scripts/simulate_subject.py"
