"""The study's closing summary: where the results are, epsilon-ranks, first pivots, Table 1."""

from facemotion.study.adapter import run_step


def main(sm, log, prov):
    import pandas as pd

    from facemotion.study.provenance import write_artifact
    from facemotion.study.summary import study_summary

    p = sm.params
    rank = selected = None
    if "rank_summary" in sm.input.keys():
        rank = pd.read_csv(sm.input.rank_summary, sep="\t")
        selected = pd.read_csv(sm.input.selected, sep="\t", dtype=str, keep_default_na=False)
    lips = {ls: pd.read_csv(path, sep="\t")
            for ls, path in zip(p.lip_subjects, sm.input.lips, strict=True)}
    sentences = {label: pd.read_csv(path, sep="\t", dtype={"sentence": str})
                 for label, path in zip(p.dataset_labels, sm.input.sentences, strict=True)}
    comparison = (pd.read_csv(sm.input.comparison, sep="\t", dtype=str, keep_default_na=False)
                  if "comparison" in sm.input.keys() else None)
    text = study_summary(p.study, p.root, rank, selected, lips, skipped=p.skipped,
                         dataset_sentences=sentences, builtin_lips=p.builtin_lips,
                         comparison=comparison)
    write_artifact(sm.output.summary, text.encode(), "study_summary", prov)


run_step(snakemake, main)  # noqa: F821
