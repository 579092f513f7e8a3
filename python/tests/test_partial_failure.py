"""Partial failure in Python (docs/FORMATS.md "Partial failure"): ``fit_table`` skips
measurement rows whose status is not ok and gives a target with too few usable rows the
status ``invalid_input``; ``strict=True`` raises instead, as ``polarid fit --strict``."""

import math

import pytest

import polarid


def write(tmp_path, text):
    p = tmp_path / "m.csv"
    p.write_text(text)
    return p


ROWS = (
    "target,class,beta_deg,dolp,dolp_se,status,reason\n"
    "A,al,45,0.2,0.01,,\n"
    "A,al,50,0.3,0.01,ok,\n"
    "A,al,55,0.4,0.01,,\n"
    "B,cu,45,0.2,0.01,,\n"
    "B,cu,50,nan,,dark,capture 2: too dark\n"
    "B,cu,55,0.4,0.01,,\n"
)


def test_fit_table_skips_rows_and_reports_unfittable_targets(tmp_path):
    t = polarid.fit_table(write(tmp_path, ROWS))
    assert t["status"] == ["ok", "invalid_input"]
    assert math.isnan(t["n"][1])
    assert t["measurements"][1] == 2
    assert "line 6 dark" in t["reason"][1]


def test_fit_table_strict_raises(tmp_path):
    with pytest.raises(ValueError, match="line 6"):
        polarid.fit_table(write(tmp_path, ROWS), strict=True)
