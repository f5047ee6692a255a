"""The closing summary says which sentences trained and which were held out, and leaves out
the built-in virtual lip talker's table in a study of the user's own recordings."""

import pandas as pd

from facemotion.study.summary import study_summary, take_lines


def sentences(train, held):
    return pd.DataFrame({"sentence": train + held,
                         "role": ["train"] * len(train) + ["heldout"] * len(held)})


def lip_table():
    return pd.DataFrame({"paper_definition": [True], "view": ["xyz_8_points"],
                         "covariance": ["10_modes"], "mse_per_dof_model_units2": [0.5],
                         "paper_mse_per_dof_model_units2": [0.001]})


def test_take_lines_name_training_and_heldout_sentences():
    lines = take_lines({
        "P01": sentences([f"take{i}" for i in range(1, 9)], ["take9", "take10"]),
        "P02": sentences(["a", "b"], []),
    })
    assert lines == [
        "  P01: trained on 8 (take1, take2, take3, ..., take8); held out 2 (take9, take10)",
        "  P02: trained on 2 (a, b); none held out (no held-out error)",
    ]


def test_builtin_lip_talker_is_left_out_of_an_own_data_study():
    lips = {"virtual": lip_table(), "mine": lip_table()}
    own = study_summary("lab", "results/lab", lips=lips, builtin_lips=["virtual"],
                        dataset_sentences={"P01": sentences(["t1"], ["t2"])})
    assert "Sentences (<dataset>/data/sentences.tsv):" in own
    assert "  P01: trained on 1 (t1); held out 1 (t2)" in own
    assert "  virtual: view" not in own and "  mine: view" in own
    assert ("Lip model: run on the built-in virtual lip talker 'virtual', not on your "
            "recordings; its table is lips/virtual/reconstruction.tsv") in own
    paper = study_summary("paper", "results/paper", lips=lips)
    assert "  virtual: view" in paper and "Lip model: run on the built-in" not in paper
    assert "Sentences (" not in paper
