"""How stable are the paper's conclusions across virtual talkers?"""

import pandas as pd

from facemotion.plots.cross_subject import plot_talkers
from facemotion.study.adapter import run_step
from facemotion.study.outputs import figure_files
from facemotion.study.provenance import save_figure, write_table
from facemotion.study.sweeps import top_k_frequency

NAMED = {"40": "lower_lip_40", "56": "jaw_56", "34": "left_corner_34", "38": "right_corner_38",
         "36": "upper_lip_36"}


def main(sm, log, prov):
    rows, selected = [], {"order": list(range(1, 17))}
    for talker, r_path, c_path in zip(sm.params.talkers, sm.input.r_values, sm.input.curves,
                                      strict=True):
        r = pd.read_csv(r_path, sep="\t", dtype={"marker": str})
        curve = pd.read_csv(c_path, sep="\t").set_index("k")
        order = list(r["marker"])
        selected[talker] = order[:16]
        row = {"talker": talker, "first_pivots": ",".join(order[:10])}
        for label, name in NAMED.items():
            row[f"rank_{name}"] = order.index(label) + 1 if label in order else -1
        row["heldout_mean_abs_error_mm_k10"] = float(curve.loc[10, "mean_abs_error_mm"])
        rows.append(row)
    table = pd.DataFrame(rows)
    write_table(table, sm.output.talkers, "summary", prov)
    freq = top_k_frequency(pd.DataFrame(selected), k=10)
    write_table(freq, sm.output.talkers_top10, "summary", prov)
    fig = plot_talkers(table, freq)
    save_figure(fig, figure_files(sm.output, "png"), "talkers", prov)


run_step(snakemake, main)  # noqa: F821
