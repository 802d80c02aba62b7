"""Heading detector: tilt compensation, wrapping, calm-window statistics, combination."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from aeromag._core.angles import wrap_deg
from aeromag.detection.alarms import Alarms
from aeromag.detection.combine import combine_alarms
from aeromag.detection.heading import (
    heading_detector,
    mag_heading_from_flux,
    parse_calm_window,
)
from aeromag.errors import InputError


def ned_to_body(phi, theta, psi):
    """NED->body direction cosine matrices (aerospace ZYX), shape (n, 3, 3)."""
    cph, sph, cth, sth = np.cos(phi), np.sin(phi), np.cos(theta), np.sin(theta)
    cps, sps = np.cos(psi), np.sin(psi)
    c = np.empty((len(phi), 3, 3))
    c[:, 0] = np.stack([cth * cps, cth * sps, -sth], axis=1)
    c[:, 1] = np.stack([sph * sth * cps - cph * sps, sph * sth * sps + cph * cps, sph * cth], 1)
    c[:, 2] = np.stack([cph * sth * cps + sph * sps, cph * sth * sps - sph * cps, cph * cth], 1)
    return c


def test_wrap():
    assert wrap_deg(180.0) == -180.0
    assert np.allclose(wrap_deg([359.0, -181.0, 10.0]), [-1.0, 179.0, 10.0])


@pytest.mark.parametrize("dec", [0.0, 12.5])
def test_tilt_compensated_heading(dec):
    rng = np.random.default_rng(0)
    n = 500
    psi = rng.uniform(-np.pi, np.pi, n)
    th = np.deg2rad(rng.uniform(-30, 30, n))
    ph = np.deg2rad(rng.uniform(-30, 30, n))
    inc, d = np.deg2rad(65.0), np.deg2rad(dec)
    b_ned = 50000 * np.array([np.cos(inc) * np.cos(d), np.cos(inc) * np.sin(d), np.sin(inc)])
    b = np.einsum("nij,j->ni", ned_to_body(ph, th, psi), b_ned)
    mh = mag_heading_from_flux(b[:, 0], b[:, 1], b[:, 2], np.rad2deg(th), np.rad2deg(ph), dec)
    assert np.max(np.abs(wrap_deg(mh - np.rad2deg(psi)))) < 1e-6


def test_detector_calm_window_and_alarm():
    rng = np.random.default_rng(3)
    t = np.arange(1000) * 0.1
    mh = (350 + rng.normal(0, 0.5, t.size)) % 360       # straddles north: wrap matters
    mh[700:] += 10.0
    df = pd.DataFrame({"time": t, "heading": np.full(t.size, 351.0), "mag_heading": mh % 360})
    res = heading_detector(df)
    assert res.mean_deg == pytest.approx(1.0, abs=0.2)
    assert res.sigma_deg == pytest.approx(0.5, rel=0.2)
    assert res.alarm[700:].all() and res.alarm[:700].sum() <= 2
    res2 = heading_detector(df, calm_window="10:40")
    assert res2.n_calm == 301
    with pytest.raises(InputError, match="calm window"):
        heading_detector(df, calm_window="200:300")
    with pytest.raises(InputError):
        parse_calm_window("abc")
    assert parse_calm_window("5:9") == (5.0, 9.0) and parse_calm_window(None) == 30.0


def test_combine():
    tr = np.array([0, 1, 0, 0, 1, 0], bool)
    hd = np.array([0, 0, 0, 1, 0, 0], bool)
    legs = np.array([0, 0, 0, 0, 0, -1])
    assert combine_alarms([tr, hd], legs, "or").tolist() == [0, 1, 0, 1, 1, 0]
    assert combine_alarms([tr, hd], legs, "and").tolist() == [0, 0, 0, 1, 1, 0]
    assert combine_alarms([tr, None], legs, "and").tolist() == [0, 1, 0, 0, 1, 0]
    with pytest.raises(InputError):
        combine_alarms([tr, hd], legs, "xor")


def test_combine_any_number_of_detectors():
    legs = np.array([0, 0, 0, 0, 1, 1, -1])
    a = np.array([0, 1, 0, 0, 0, 1, 1], bool)
    b = np.array([0, 0, 1, 0, 0, 1, 1], bool)
    c = Alarms(name="pf", time_s=np.arange(7.0), stat=np.arange(7.0), threshold=2.5,
               alarm=np.array([0, 0, 0, 1, 0, 1, 1], bool))
    assert combine_alarms([a, b, c], legs, "or").tolist() == [0, 1, 1, 1, 0, 1, 0]
    # confirmation: all three have fired on the leg by the sample
    assert combine_alarms([a, b, c], legs, "and").tolist() == [0, 0, 0, 1, 0, 1, 0]
    assert combine_alarms([], legs).tolist() == [0] * 7


def test_heading_detector_returns_alarms():
    t = np.arange(0, 60, 0.1)
    rng = np.random.default_rng(1)
    mh = rng.normal(0, 0.5, t.size)
    mh[400:] += 10.0
    df = pd.DataFrame({"time": t, "heading": np.zeros_like(t), "mag_heading": mh % 360})
    res = heading_detector(df)
    assert isinstance(res, Alarms) and res.name == "heading"
    assert res.threshold == pytest.approx(5 * res.sigma_deg)
    assert res.first_alarm_time == pytest.approx(40.0)
    assert not res.alarm[:400].any() and res.alarm[400:].all()
