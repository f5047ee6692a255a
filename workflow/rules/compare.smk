# The papers' quantitative statements beside ours (results/tables/paper_comparison.tsv).

# Datasets whose labels are Lucero & Munhall's (Table I): the comparison reads their outputs.
PAPER_LABELS = ("S1", "S2a", "S2b", "S2a*", "S2b*")
COMPARISON_DATASETS = {
    ds.label: d for d, ds in DATASETS.items() if ds.label in PAPER_LABELS
}
_lip_virtual = [
    ls for ls, spec in config["lips"]["subjects"].items() if spec["source"] == "virtual"
]
COMPARISON_LIP_SUBJECT = (
    "virtual" if "virtual" in _lip_virtual else (_lip_virtual[0] if _lip_virtual else None)
)


def comparison_outputs():
    if not COMPARISON_DATASETS and COMPARISON_LIP_SUBJECT is None:
        return []
    return ["results/tables/paper_comparison.tsv"]


def comparison_inputs(wildcards):
    """Named inputs: the tables, then per paper dataset its R values, stability, error curve,
    trajectory and (when k = 10 is fitted) coefficients."""
    inp = {}
    if DATASETS:
        inp["selected"] = "results/tables/selected_markers.tsv"
        inp["rank_summary"] = "results/tables/rank_summary.tsv"
    for label, d in COMPARISON_DATASETS.items():
        inp[f"r_values__{d}"] = f"results/{d}/qr/r_values.tsv"
        inp[f"stability__{d}"] = f"results/{d}/qr/stability.tsv"
        if d in EVAL_DATASETS:
            inp[f"curve__{d}"] = f"results/{d}/eval/error_curve.tsv"
            inp[f"trajectory__{d}"] = f"results/{d}/eval/trajectory_errors.tsv"
        if 10 in config["fit"]["k"]:
            inp[f"coefficients__{d}"] = f"results/{d}/fit/coefficients_k10.tsv"
    if COMPARISON_LIP_SUBJECT is not None:
        ls = COMPARISON_LIP_SUBJECT
        inp["lip_reconstruction"] = f"results/lips/{ls}/reconstruction.tsv"
        inp["lip_counts"] = f"results/lips/{ls}/model_counts.tsv"
    return inp


rule compare_with_papers:
    input:
        unpack(comparison_inputs),
    output:
        table="results/tables/paper_comparison.tsv",
        meta="results/tables/paper_comparison.meta.json",
        png=report(
            "results/figures/paper_comparison.png",
            caption="../report/paper_comparison.rst",
            category="0. Summary",
        ),
        pdf="results/figures/paper_comparison.pdf",
        fig_meta="results/figures/paper_comparison.meta.json",
    log:
        "results/logs/compare_with_papers.log",
    conda:
        "../envs/facemotion.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=5,
    params:
        datasets=COMPARISON_DATASETS,
        lip_subject=COMPARISON_LIP_SUBJECT,
        tolerance_mm=0.5,
        r_normalisation=config["qr"]["r_normalisation"],
    script:
        "../../scripts/compare_with_papers.py"
