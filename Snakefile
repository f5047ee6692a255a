# facemotion: how the human face moves during speech.
# Lucero & Munhall (2008) kinematic regions and Basu & Pentland (1997) lip model.
# Every output of a study goes under results/<study>/ (the `study` setting; <results> in paths).


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/simulate.smk"
include: "workflow/rules/data.smk"
include: "workflow/rules/qr.smk"
include: "workflow/rules/fit.smk"
include: "workflow/rules/eval.smk"
include: "workflow/rules/animate.smk"
include: "workflow/rules/tables.smk"
include: "workflow/rules/lips.smk"
include: "workflow/rules/sweeps.smk"
include: "workflow/rules/compare.smk"
include: "workflow/rules/stream.smk"
include: "workflow/rules/design.smk"


# One job per dataset (per virtual subject, lip subject, k, sweep point) through wildcards;
# the tables and figures across datasets are aggregation rules of their own. Scheduling on few
# cores (rules' priority:): the virtual subjects and their loading first (every analysis waits
# for them), then the analysis jobs longest first (animation, region maps, held-out
# evaluation, sentence sweep, subsets, ranking, the lip model, the redundancy check), and the
# comparison with the papers as soon as its inputs exist.


# Small aggregation rules (tables and figures across datasets, the summary, the manifest) run
# on the machine Snakemake runs on, never as cluster jobs of their own.
localrules:
    all,
    summarise_ranking,
    summarise_heldout,
    summarise_sweep,
    summarise_talkers,
    summarise_lip_seeds,
    compare_with_papers,
    summarise_study,
    write_manifest,
    render_face_page,


rule all:
    default_target: True
    input:
        final_outputs(),
    message:
        "all: study '{STUDY}' complete".format(STUDY=STUDY)


onsuccess:
    print_closing_summary()


# The input digests are cached once the whole study is parsed (a refused parse writes
# nothing, nor does a dry run of a study that has not run yet).
if not workflow.dryrun or Path(RESULTS).is_dir():
    _DIGESTS.save()
_PARSE.done()
