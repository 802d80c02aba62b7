"""The Python API records a run's warnings in its JSON, as the command line does (issue 15).

``aeromag compensate`` wraps the run in one output set whose warning capture puts every
warning logged while reading, fitting and applying into OUT.json's ``warnings``.  A notebook
calling :func:`aeromag.workflows.compensate_file` or :func:`aeromag.workflows.calibrate_file`
directly got the warnings on its logger only: the file it wrote said nothing.  The log here has
its fluxgate in microtesla (a --units-worthy warning) and is compensated with the shipped model.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from aeromag.workflows.compensate import calibrate_file, compensate_file

SAMPLES = Path(__file__).resolve().parents[1] / "data_samples"


@pytest.fixture(scope="module")
def ut_log(tmp_path_factory) -> Path:
    df = pd.read_csv(SAMPLES / "survey.csv")
    for c in ("flux_x", "flux_y", "flux_z"):
        df[c] = df[c] / 1000.0  # nT -> uT, columns still called nT by the contract
    p = tmp_path_factory.mktemp("api_warn") / "survey_uT.csv"
    df.to_csv(p, index=False)
    return p


def _warned(rep: dict) -> list[str]:
    return [w for w in rep.get("warnings", []) if "uT" in w or "µT" in w or "microtesla" in w]


@pytest.fixture(scope="module")
def model(tmp_path_factory) -> Path:
    m = tmp_path_factory.mktemp("api_model") / "model.json"
    calibrate_file(SAMPLES / "calibration.csv", m)
    return m


def test_compensate_file_records_the_warning_in_out_json(ut_log, model, tmp_path):
    out = tmp_path / "o.csv"
    compensate_file(ut_log, out, model=model)
    rep = json.loads(out.with_suffix(".json").read_text())
    assert _warned(rep), rep.get("warnings")


def test_calibrate_file_records_the_warning_in_the_model(tmp_path):
    df = pd.read_csv(SAMPLES / "calibration.csv")
    for c in ("flux_x", "flux_y", "flux_z"):
        df[c] = df[c] / 1000.0
    log = tmp_path / "cal_uT.csv"
    df.to_csv(log, index=False)
    m = tmp_path / "m.json"
    calibrate_file(log, m)
    rep = json.loads(m.read_text())
    assert _warned(rep), rep.get("warnings")
