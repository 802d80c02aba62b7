"""A setting that cannot act is refused from Python as on the command line.

``CompensationConfig(screen=False, noise_factor=2)`` given to ``am.compensate`` used to run and
ignore ``noise_factor``; ``aeromag compensate --no-screen --noise-factor 2`` refused it.  One
rule (:func:`aeromag.compensation.config.unused_options`) decides both; the library's message
names Python keywords, the command line's flags.  Values left at their defaults are never
refused, so internal callers that build configurations do not trip it.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from typer.testing import CliRunner

import aeromag as am
from aeromag.cli import app
from aeromag.cli._options import OPTIONS, flag_message
from aeromag.compensation.config import (
    BATCH_FIT_ONLY,
    FIT_ONLY,
    SCREEN_ONLY,
    CompensationConfig,
    changed_options,
    refuse_unused_options,
    unused_options,
)
from aeromag.errors import InputError
from aeromag.io import read_log

runner = CliRunner()
SAMPLES = Path(__file__).resolve().parents[1] / "data_samples"


@pytest.fixture(scope="module")
def survey():
    return read_log(SAMPLES / "survey.csv")


@pytest.fixture(scope="module")
def model():
    return am.calibrate(read_log(SAMPLES / "calibration.csv")).model


def _error(r) -> str:  # noqa: ANN001 - click Result
    return (r.stderr if r.stderr_bytes is not None else r.output).strip()


# --------------------------------------------------------------------------- Python API
def test_compensate_refuses_screening_option_with_screen_false(survey):
    cfg = CompensationConfig(screen=False, noise_factor=2)
    with pytest.raises(InputError) as exc:
        am.compensate(survey, cfg)
    assert str(exc.value) == ("noise_factor=2 steers the screening, and screen=False skips it: "
                              "nothing uses it; drop noise_factor=2 (or drop screen=False)")


@pytest.mark.parametrize("kw", [dict(min_excess=2.0), dict(pca_variance=0.5),
                                dict(screen_quantile=0.9), dict(min_excess_nT=0.1),
                                dict(max_iter=3), dict(inlier_excess=3.0)])
def test_calibrate_refuses_screening_options_with_screen_false(kw):
    cal = read_log(SAMPLES / "calibration.csv")
    with pytest.raises(InputError, match=rf"^{next(iter(kw))}=.* steers the screening"):
        am.calibrate(cal, CompensationConfig(screen=False, **kw))


def test_defaults_and_shrink_are_not_refused(survey):
    # a default value typed out is no change; shrink still acts without screening
    cfg = CompensationConfig(screen=False, noise_factor=3, min_excess=1.5, shrink=0.0,
                             band_hz=[0.1, 0.9], terms="16")
    assert changed_options(cfg) == {"screen", "shrink"}
    assert unused_options(cfg) == []
    res = am.compensate(survey, cfg)
    assert res.report.screening.shrink == 0.0


def test_applying_a_model_refuses_fit_options(survey, model):
    with pytest.raises(InputError) as exc:
        am.compensate(survey, CompensationConfig(ridge=1e-3), model=model)
    assert str(exc.value) == ("ridge=0.001 steers a fit, and model=MODEL applies a saved model:"
                              " nothing is fitted; drop ridge=0.001 (or drop model=MODEL to fit)")
    for kw in (dict(terms="9"), dict(decimate=False), dict(screen=False),
               dict(noise_factor=2.0)):
        with pytest.raises(InputError, match="applies a saved model"):
            am.compensate(survey, CompensationConfig(**kw), model=model)


def test_applying_a_model_keeps_what_the_application_uses(survey, model):
    cfg = CompensationConfig(lowpass_hz=0.5, segment_seconds=30.0, max_interference=0.3)
    out = am.compensate(survey, cfg, model=model)
    assert out.report.model_source != "fitted"


def test_lowpass_with_filter_output_false_is_refused(survey):
    cfg = CompensationConfig(filter_output=False, lowpass_hz=0.5)
    with pytest.raises(InputError, match=r"^lowpass_hz=0\.5 sets the final low-pass of mag_comp,"
                       r" and filter_output=False leaves mag_comp unfiltered"):
        am.compensate(survey, cfg)


def test_compensate_file_refuses_before_writing(tmp_path):
    out = tmp_path / "out.csv"
    with pytest.raises(InputError, match="screen=False skips it"):
        am.workflows.compensate_file(SAMPLES / "survey.csv", out,
                           CompensationConfig(screen=False, min_excess=3.0))
    assert not out.exists() and not out.with_suffix(".json").exists()


def test_online_rule():
    assert "terms" not in BATCH_FIT_ONLY and set(BATCH_FIT_ONLY) < set(FIT_ONLY)
    assert unused_options(CompensationConfig(terms="9"), online=True) == []
    assert unused_options(CompensationConfig(fom=False), online=True) == []
    found = unused_options(CompensationConfig(ridge=0.1, fom=True), online=True)
    assert [(u.keyword, u.cause) for u in found] == [("ridge", "online"), ("fom", "online_fom")]
    with pytest.raises(InputError, match=r"^max_condition=1000000\.0 steers the batch fit"):
        refuse_unused_options(CompensationConfig(max_condition=1e6), online=True)


@pytest.mark.xfail(strict=True, reason="needs refuse_unused_options(cfg, online=True) in "
                   "aeromag/workflows/online_compensate.compensate_online_frame (not this "
                   "change's file); remove this mark when it is there")
def test_compensate_online_file_refuses_batch_fit_options(tmp_path):
    from aeromag.workflows.online_compensate import compensate_online_file

    with pytest.raises(InputError, match="fits sample by sample"):
        compensate_online_file(SAMPLES / "survey.csv", tmp_path / "o.csv",
                               CompensationConfig(ridge=0.1))


def test_internal_configurations_do_not_trip_it():
    # the scikit-learn estimator fits without screening, with its own checks
    est = am.TollesLawsonRegressor(ridge=0.1, max_condition=1e6)
    assert unused_options(est._config()) == []
    # calibrate turns the FOM on: no online run, nothing refused
    assert unused_options(dataclasses.replace(CompensationConfig(), fom=True)) == []


# ---------------------------------------------------------- one rule, two spellings
def test_library_message_maps_to_flags():
    u = unused_options(CompensationConfig(screen=False, noise_factor=2))[0]
    assert flag_message(u.message()) == (
        "--noise-factor 2 steers the screening, and --no-screen skips it: nothing uses it; "
        "drop --noise-factor 2 (or drop --no-screen)")


@pytest.mark.parametrize("opt", [o for o in OPTIONS if o.config in FIT_ONLY and o.flags
                                 and "calibrate" in o.commands], ids=lambda o: o.flags[-1])
def test_cli_no_screen_refuses_exactly_the_screening_options(tmp_path, opt):
    if opt.config == "screen":
        pytest.skip("--no-screen itself")
    # the extended fit's options take column names: values that fail fast (no such column)
    text = {"reference": "nosuch", "extras": "nosuch", "estimator": "pls"}
    value = [] if opt.type is bool else [text.get(opt.config) or
                                         ("9" if opt.config == "terms" else "0.5")]
    out = tmp_path / "m.json"
    r = runner.invoke(app, ["calibrate", str(SAMPLES / "calibration.csv"), "-o", str(out),
                            "--no-screen", opt.flags[-1], *value])
    if opt.config in SCREEN_ONLY:
        assert r.exit_code == 1, r.output
        assert _error(r) == (f"error: {opt.flags[-1]} steers the screening, and --no-screen "
                             f"skips it: nothing uses it; drop {opt.flags[-1]} (or drop "
                             "--no-screen)")
        assert not out.exists()
    else:
        assert "--no-screen skips it" not in r.output
        # the library ran the same configuration: it refuses what the CLI refuses, no more
        kw = {opt.config: opt.to_config(True) if opt.to_config else
              (value[0] if opt.config in ("terms", "reference", "extras") else 0.5)}
        if opt.config == "estimator":
            kw = {"estimator": "pls", "extras": ("nosuch",)}
        assert unused_options(CompensationConfig(screen=False, **kw)) == []


def test_cli_refuses_a_typed_default_the_library_cannot_see(tmp_path):
    # on the command line a typed option was given even at its default value
    r = runner.invoke(app, ["compensate", str(SAMPLES / "survey.csv"), "-o",
                            str(tmp_path / "o.csv"), "--no-screen", "--noise-factor", "3"])
    assert r.exit_code == 1 and "--noise-factor steers the screening" in _error(r)


def test_cli_no_filter_refuses_lowpass(tmp_path):
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["compensate", str(SAMPLES / "survey.csv"), "-o", str(out),
                            "--no-filter", "--lowpass", "0.5"])
    assert r.exit_code == 1, r.output
    assert _error(r) == ("error: --lowpass sets the final low-pass of mag_comp, and --no-filter "
                         "leaves mag_comp unfiltered: nothing uses it; drop --lowpass (or drop "
                         "--no-filter)")
    assert not out.exists()


def test_cli_online_refuses_what_the_library_refuses(tmp_path):
    r = runner.invoke(app, ["compensate", str(SAMPLES / "survey.csv"), "-o",
                            str(tmp_path / "o.csv"), "--online", "--ridge", "0.1"])
    assert r.exit_code == 1
    lib = unused_options(CompensationConfig(ridge=0.1), online=True)[0]
    assert _error(r) == "error: " + lib.message("--ridge", "--online", "or drop --online")
