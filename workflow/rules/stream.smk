# Streamed loading scattered over jobs (target `stream`, not part of `all`): one job per take
# reads it in blocks within memory.max_gib (facemotion.ingest.scatter), gather rules add the
# head reference and the Gram of the training takes, then rank it and evaluate the held-out
# takes block by block. On a cluster (profiles/slurm) the takes of a dataset load on as many
# nodes as there are takes.


localrules:
    stream,


rule stream:
    input:
        expand("<results>/{dataset}/stream/r_values.tsv", dataset=list(DATASETS)),
        expand(
            "<results>/{dataset}/stream/error_curve.tsv",
            dataset=[d for d in DATASETS if DATASETS[d].heldout],
        ),
    message:
        "stream: every dataset loaded take by take, its Gram gathered"


rule scan_take_heads:
    input:
        data=load_inputs,
    output:
        npz="<results>/{dataset}/stream/heads/{take}.npz",
    log:
        "<results>/logs/scan_take_heads/{dataset}/{take}.log",
    wildcard_constraints:
        take=r"t\d{3}",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=lambda wc: int(1536 * config["memory"]["max_gib"]),
        runtime=60,
    params:
        take=stream_params,
        gaps=config["gaps"],
        checks=config["checks"],
        max_gib=config["memory"]["max_gib"],
    message:
        "scan_take_heads {wildcards.dataset} {wildcards.take}: read in blocks, checked, head points"
    script:
        "../../scripts/stream_scan_heads.py"


rule gather_head_reference:
    input:
        heads=stream_heads,
    output:
        npz="<results>/{dataset}/stream/head_reference.npz",
    log:
        "<results>/logs/gather_head_reference/{dataset}.log",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    params:
        ds=lambda wc: dataset_params(SUBJECTS, DATASETS, wc.dataset),
    message:
        "gather_head_reference {wildcards.dataset}: the median head over every take"
    script:
        "../../scripts/gather_head_reference.py"


rule stream_take:
    input:
        data=load_inputs,
        reference="<results>/{dataset}/stream/head_reference.npz",
    output:
        npz="<results>/{dataset}/stream/takes/{take}.npz",
        gram="<results>/{dataset}/stream/takes/{take}.gram.npz",
    log:
        "<results>/logs/stream_take/{dataset}/{take}.log",
    wildcard_constraints:
        take=r"t\d{3}",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=lambda wc: int(1536 * config["memory"]["max_gib"]),
        runtime=60,
    params:
        take=stream_params,
        gaps=config["gaps"],
        checks=config["checks"],
        neutral=config["neutral"],
        max_gib=config["memory"]["max_gib"],
    message:
        "stream_take {wildcards.dataset} {wildcards.take}: blocks -> A on disk and its Gram"
    script:
        "../../scripts/stream_take.py"


rule gather_gram:
    input:
        grams=stream_grams,
    output:
        npz="<results>/{dataset}/stream/gram.npz",
    log:
        "<results>/logs/gather_gram/{dataset}.log",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    message:
        "gather_gram {wildcards.dataset}: G = sum of the training takes' Grams"
    script:
        "../../scripts/gather_gram.py"


rule rank_stream:
    input:
        gram="<results>/{dataset}/stream/gram.npz",
    output:
        **table("r_values", "<results>/{dataset}/stream/r_values.tsv"),
    log:
        "<results>/logs/rank_stream/{dataset}.log",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=10,
    params:
        r_normalisation=config["qr"]["r_normalisation"],
    message:
        "rank_stream {wildcards.dataset}: the gathered Gram ranked (L&M Fig. 2)"
    script:
        "../../scripts/rank_stream.py"


rule evaluate_stream:
    input:
        gram="<results>/{dataset}/stream/gram.npz",
        heldout=stream_heldout_parts,
    output:
        **table("curve", "<results>/{dataset}/stream/error_curve.tsv"),
    log:
        "<results>/logs/evaluate_stream/{dataset}.log",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=lambda wc: int(1536 * config["memory"]["max_gib"]),
        runtime=30,
    params:
        k_max=config["qr"]["k_max"],
        heldout=lambda wc: list(stream_heldout(wc.dataset).values()),
    message:
        "evaluate_stream {wildcards.dataset}: held-out error against k, block by block (L&M Fig. 10)"
    script:
        "../../scripts/evaluate_stream.py"
