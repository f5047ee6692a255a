"""Parse-time checks of the settings against the data's counts: refused, never clamped."""

import copy
import re

import pytest
import yaml
from helpers import SCHEMAS

from facemotion.errors import InputError
from facemotion.study.settings import (
    DataCounts,
    check_lip_frames,
    check_settings,
    check_sweep,
    validate_config,
)
from facemotion.study.sheet import n_heldout

SCHEMA = SCHEMAS / "config.schema.yaml"


@pytest.fixture()
def config():
    cfg = yaml.safe_load((SCHEMA.parent.parent.parent / "config" / "smoke.yaml").read_text())
    validate_config(cfg, SCHEMA)  # fills in the defaults
    return cfg


COUNTS = {"S1": DataCounts(markers=20, train=4, heldout=2, labels=tuple(map(str, range(20)))),
          "S2": DataCounts(markers=20, train=5, heldout=0, labels=tuple(map(str, range(20))))}


def test_defaults_pass(config):
    check_settings(config, COUNTS)


@pytest.mark.parametrize("path,value,match", [
    (("fit", "k"), [20], r"setting fit\.k: k = 20 main markers must be fewer than the markers "
                         r"of dataset S1, which analyses 20 markers"),
    (("animation", "k"), 20, r"setting animation\.k: k = 20"),
    (("animation", "sentences"), 3, r"setting animation\.sentences: 3 sentences to animate but "
                                    r"dataset S1, which holds out 2"),
    (("eval", "trajectory_k"), 100, r"setting eval\.trajectory_k: k = 100"),
    (("eval", "trajectory_sentence"), 9, r"setting eval\.trajectory_sentence: held-out sentence"
                                         r" 9 does not exist in dataset S1"),
    (("qr", "agreement_k"), [5, 21], r"setting qr\.agreement_k: k = 21 exceeds"),
    (("qr", "sweep_pivots"), 21, r"setting qr\.sweep_pivots: 21 pivots"),
    (("qr", "optimality_k_max"), 20, r"setting qr\.optimality_k_max: 20 must be fewer"),
    (("fit", "orthogonal_maps"), 5, r"setting fit\.orthogonal_maps: 5 maps.*k = 4"),
    (("eval", "selection_resamples"), 5000,
     r"setting eval\.selection_resamples: 5000 is more than the 1000 resamples"),
])
def test_each_setting_is_refused_not_clamped(config, path, value, match):
    cfg = copy.deepcopy(config)
    cfg[path[0]][path[1]] = value
    with pytest.raises(InputError, match=match):
        check_settings(cfg, COUNTS)


def test_held_out_settings_do_not_apply_without_held_out_sentences(config):
    cfg = copy.deepcopy(config)
    cfg["eval"]["trajectory_sentence"] = 3
    check_settings(cfg, {"S2": COUNTS["S2"]})
    cfg["animation"]["enabled"] = False
    cfg["animation"]["sentences"] = 5
    check_settings(cfg, {"S1": DataCounts(20, 4, 3)})


def test_heldout_fraction_zero_holds_nothing_out():
    assert [n_heldout(n, 0) for n in (1, 2, 10, 40)] == [0, 0, 0, 0]
    assert [n_heldout(n, 0.25) for n in (1, 2, 10, 40)] == [0, 1, 2, 10]
    assert n_heldout(3, 0.01) == 1  # asked for some: at least one


def test_sweeps_and_lips(config):
    with pytest.raises(InputError, match=r"sweeps\.s\.k: k=20"):
        check_sweep("s", {"k": [20]}, COUNTS)
    with pytest.raises(InputError, match=r"sweeps\.s\.train_sentences: 5 exceeds the 4"):
        check_sweep("s", {"datasets": ["S1"], "train_sentences": [5]}, COUNTS)
    with pytest.raises(InputError, match=r"sweeps\.s\.marker_subsets\.lips: marker\(s\) 40"):
        check_sweep("s", {"marker_subsets": {"lips": ["1", "40"]}}, COUNTS)
    with pytest.raises(InputError, match=r"sweeps\.s\.datasets: unknown dataset 'X'"):
        check_sweep("s", {"datasets": ["X"]}, COUNTS)
    check_lip_frames(config, {"virtual": 60})
    with pytest.raises(InputError, match=r"lips\.test_frames.*outside 1\.\.50"):
        check_lip_frames(config, {"virtual": 50})
    cfg = copy.deepcopy(config)
    cfg["lips"]["n_modes"] = 50
    with pytest.raises(InputError, match=r"setting lips\.n_modes: 50 modes need more than 50"):
        check_lip_frames(cfg, {"virtual": 60})


def test_schema_errors_are_one_line_naming_the_setting(config):
    cfg = copy.deepcopy(config)
    cfg["qr"]["tolerances_mm"] = [-1]
    with pytest.raises(InputError, match=r"^setting qr\.tolerances_mm\.0: -1 is less than or "
                                         r"equal to the minimum of 0$"):
        validate_config(cfg, SCHEMA)
    cfg = copy.deepcopy(config)
    cfg["animation"]["formt"] = "gif"
    with pytest.raises(InputError, match=r"^setting animation: Additional properties .*formt"):
        validate_config(cfg, SCHEMA)


@pytest.mark.parametrize("qr,match", [
    ({"k_max": 20}, r"setting qr\.k_max: 20 must be fewer than the markers of dataset S1"),
    ({"k_max": 2}, r"setting fit\.k: k = \d+ exceeds qr\.k_max = 2"),
    ({"method": "randomized"}, r"setting qr\.k_max: the randomized route"),
])
def test_k_max_refused_never_clamped(config, qr, match):
    cfg = copy.deepcopy(config)
    cfg["qr"].update(qr)
    with pytest.raises(InputError, match=match):
        check_settings(cfg, COUNTS)


def test_k_max_within_the_data_passes(config):
    cfg = copy.deepcopy(config)
    cfg["qr"].update({"k_max": 19, "method": "randomized"})
    check_settings(cfg, COUNTS)
    with pytest.raises(InputError, match=r"setting qr\.k_max"):
        validate_config({**cfg, "qr": {**cfg["qr"], "k_max": 0}}, SCHEMA)


def test_nan_and_infinity_in_any_setting_are_errors(tmp_path):
    """NaN passes every schema minimum and maximum (the comparisons are false), so it is
    refused before the schema: a NaN tolerance would otherwise give an epsilon-rank."""
    from facemotion.study.settings import validate_config

    schema = SCHEMAS / "config.schema.yaml"
    for config, where in (({"qr": {"tolerances_mm": [0.5, float("nan")]}}, "qr.tolerances_mm.1"),
                          ({"heldout_fraction": float("inf")}, "heldout_fraction")):
        with pytest.raises(InputError, match=rf"^setting {re.escape(where)}: (nan|inf) is not a "
                                             "finite number$"):
            validate_config(config, schema)


def test_lip_settings_from_the_config(config):
    """The schema's defaults as the lip model's settings: the paper's frames 1-140 / 141-150
    made 0-based, 'auto' noise as the probabilistic-PCA choice, the paper's model extent;
    a noise_var that is neither a number nor 'auto' is one line naming the setting."""
    from facemotion.study.settings import lip_settings

    lips = copy.deepcopy(config["lips"])
    lips.update(train_frames="1-140", test_frames="141-150", noise_var="auto")
    s = lip_settings(lips, 150)
    assert s.train_frames == tuple(range(140)) and s.test_frames == tuple(range(140, 150))
    assert s.noise_var == "ppca" and s.model_extent == (2.35, 2.83, 5.05)
    assert s.model_kwargs()["noise_grid"] == tuple(lips["noise_var_sweep"])
    assert lip_settings({**lips, "noise_var": 1e-4, "model_extent": None}, 150).model_kwargs()[
        "model_extent"] is None
    with pytest.raises(InputError, match=r"^setting lips.noise_var: 'big' is neither a number "
                                         r"nor 'auto'$"):
        lip_settings({**lips, "noise_var": "big"}, 150)
    with pytest.raises(InputError, match=r"^setting lips.test_frames: sentence\(s\) \[151\]"):
        lip_settings({**lips, "test_frames": "141-151"}, 150)
