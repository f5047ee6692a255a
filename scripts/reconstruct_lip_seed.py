"""One seed of the virtual lip talker through the lip model: its Table 1 cells under both
estimator readings (Basu & Pentland 1997, Table 1)."""

from facemotion.lips.seeds import seed_table1
from facemotion.study.adapter import run_step
from facemotion.study.provenance import write_table
from facemotion.study.settings import lip_settings


def main(sm, log, prov):
    p = sm.params.lip
    settings = lip_settings(p, p["subject"].get("frames", 150))
    seed = int(sm.wildcards.seed)
    table = seed_table1(p["subject"], settings, seed, sm.wildcards.lip_subject)
    write_table(table, sm.output.table, "lip_table1_seed", prov)
    frontal = table[table["view"] == "xy_all_points"]
    for _, r in frontal.iterrows():
        log.info("seed %d, %s: frontal view full / %d modes = %.3g", seed,
                 r["estimator_reading"], r["n_modes"], r["full_over_modes"])


run_step(snakemake, main)  # noqa: F821
