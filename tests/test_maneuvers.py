"""Manoeuvre and heading-leg detection on the simulated calibration box."""

from __future__ import annotations

import numpy as np
import pytest

from aeromag.errors import InputError
from aeromag.qc.maneuvers import MANEUVERS, detect_maneuvers, moving_mean
from aeromag.synthetic import simulate_calibration


@pytest.fixture(scope="module")
def cal():
    return simulate_calibration(seed=3, n_boxes=1)[0]


def test_finds_the_12_manoeuvres_of_the_box(cal):
    r = detect_maneuvers(cal)
    assert r.method == "attitude"
    assert len(r.table) == 12
    assert r.complete_boxes == [0]
    got = set(zip(r.table["heading_leg"], r.table["maneuver"], strict=True))
    assert got == {(h, m) for h in range(4) for m in MANEUVERS}
    m = cal["truth_maneuver"].isin(MANEUVERS).to_numpy()
    assert (r.labels["heading_leg"].to_numpy()[m] == cal["truth_heading_leg"].to_numpy()[m]).all()
    agree = (r.labels["maneuver"].to_numpy()[m] == cal["truth_maneuver"].to_numpy()[m]).mean()
    assert agree > 0.95
    # Every detected interval lies inside the true manoeuvre of the same name.
    for row in r.table.itertuples():
        sel = (cal["time"] >= row.t_start) & (cal["time"] <= row.t_end)
        assert (cal.loc[sel, "truth_maneuver"] == row.maneuver).mean() > 0.9


def test_two_boxes_with_kept_turns():
    df = simulate_calibration(seed=4, n_boxes=2, cut_turns=False)[0]
    r = detect_maneuvers(df)
    assert r.complete_boxes == [0, 1]
    assert len(r.table) == 24
    assert (r.labels["maneuver"].to_numpy()[df["truth_maneuver"] == "turn"] == "").mean() > 0.7


def test_user_column_and_fluxgate_legs(cal):
    r = detect_maneuvers(cal, maneuver_column="truth_maneuver")
    assert r.method == "column:truth_maneuver"
    assert len(r.table) == 12
    flux_only = cal.drop(columns=["heading", "pitch", "roll"])
    r2 = detect_maneuvers(flux_only)
    assert r2.method == "fluxgate"
    m = cal["truth_maneuver"].isin(MANEUVERS).to_numpy()
    assert (r2.labels["heading_leg"].to_numpy()[m] == cal["truth_heading_leg"].to_numpy()[m]).all()
    # Pitch is always separable from roll on N/S headings (roll/yaw ambiguity documented).
    ns = r2.table[r2.table["heading"].isin(["N", "S"])]
    assert (ns["maneuver"] == "pitch").sum() >= 1


def test_errors(cal):
    with pytest.raises(InputError):
        detect_maneuvers(cal.iloc[:5])
    with pytest.raises(InputError):
        detect_maneuvers(cal, maneuver_column="nope")


def test_moving_mean_respects_stretches():
    x = np.r_[np.zeros(5), np.full(5, 10.0)]
    st = np.r_[np.zeros(5, int), np.ones(5, int)]
    assert np.allclose(moving_mean(x, st, 3), x)
    st[2] = -1
    assert np.isnan(moving_mean(x, st, 1)[2])


def test_moving_mean_equals_brute_force():
    """Shrinking windows at every stretch end, NaN outside stretches, any window size."""
    from aeromag._core.runs import run_bounds

    rng = np.random.default_rng(0)
    for n, h in [(50, 3), (7, 5), (400, 20), (30, 1)]:
        x = rng.normal(size=(n, 2))
        st = np.sort(rng.integers(0, 6, n))
        st[rng.integers(0, n, 3)] = -1
        want = np.full_like(x, np.nan)
        for a, b, _ in zip(*run_bounds(st), strict=True):
            for i in range(a, b):
                want[i] = x[max(i - h, a):min(i + h + 1, b)].mean(axis=0)
        assert np.allclose(moving_mean(x, st, h), want, rtol=1e-12, atol=1e-12,
                           equal_nan=True)


@pytest.mark.parametrize("rate_hz", [10.0, 200.0])
def test_working_rate_finds_the_same_manoeuvres(rate_hz):
    """The 2 Hz working rate (default) finds the full-rate manoeuvres, edges within 1 s, on a
    10 Hz and a 200 Hz simulated box; the labels cover every sample of the log."""
    df = simulate_calibration(seed=3, n_boxes=1, rate_hz=rate_hz)[0]
    fast = detect_maneuvers(df)
    full = detect_maneuvers(df, rate_hz=None)
    assert len(fast.labels) == len(df) and fast.complete_boxes == full.complete_boxes == [0]
    a, b = fast.table, full.table
    assert list(a["maneuver"]) == list(b["maneuver"])
    assert list(a["heading"]) == list(b["heading"])
    assert np.abs(a["t_start"] - b["t_start"]).max() < 1.0
    assert np.abs(a["t_end"] - b["t_end"]).max() < 1.0
    m = df["truth_maneuver"].isin(MANEUVERS).to_numpy()
    agree = (fast.labels["maneuver"].to_numpy()[m] == df["truth_maneuver"].to_numpy()[m]).mean()
    assert agree > 0.95
    # The table's sample counts are the labels' (every sample of a manoeuvre counted once).
    counts = np.bincount(fast.labels["maneuver_id"].to_numpy() + 1)[1:]
    assert (counts == a["n"].to_numpy()).all()


def _resolve_reference(lid, man, amb):
    """The per-leg loop the vectorised _resolve_ambiguous replaced (the rule in words)."""
    from aeromag.qc.maneuvers import MANEUVERS

    man = man.copy()
    for leg in np.unique(lid[amb]):
        runs = np.flatnonzero(lid == leg)
        sure = {int(man[r]) for r in runs if not amb[r]}
        missing = [j for j in range(len(MANEUVERS)) if j not in sure]
        unsure = [r for r in runs if amb[r]]
        if len(unsure) == len(missing):
            for r, j in zip(unsure, missing, strict=True):
                man[r] = j
    return man


def test_resolve_ambiguous_names_unsure_runs_by_the_missing_manoeuvres():
    from aeromag.qc.maneuvers import _resolve_ambiguous

    # Hand case: leg 0 has a sure pitch and two unsure runs -> roll, yaw in flight order;
    # leg 1 has one unsure run but two missing manoeuvres -> left as it was.
    lid = np.array([0, 0, 0, 1, 1])
    man = np.array([0, 2, 2, 1, 1])
    amb = np.array([False, True, True, False, True])
    notes: list[str] = []
    _resolve_ambiguous(lid, man, amb, notes)
    assert man.tolist() == [0, 1, 2, 1, 1]
    assert "(1 renamed)" in notes[0]
    rng = np.random.default_rng(3)
    for _ in range(300):
        n = int(rng.integers(1, 40))
        lid = np.sort(rng.integers(0, 8, n))
        man = rng.integers(0, 3, n)
        amb = rng.random(n) < 0.4
        want = _resolve_reference(lid, man, amb)
        _resolve_ambiguous(lid, man, amb, [])
        assert man.tolist() == want.tolist()


def test_heading_unit_vector_is_the_heading_sources():
    from aeromag.qc._heading import _heading_source, heading_unit

    df, _ = simulate_calibration(seed=2, n_boxes=1)
    df.loc[5:7, "flux_y"] = np.nan
    for cols, decl in (([], 0.0), (["heading"], 12.5), (["heading", "pitch", "roll"], -7.0)):
        d = df.drop(columns=cols)
        h, _ = _heading_source(d, decl)
        cs, ok = heading_unit(d, decl)
        assert (ok == np.isfinite(h)).all()
        np.testing.assert_allclose(cs[ok, 0], np.cos(np.deg2rad(h[ok])), atol=1e-12)
        np.testing.assert_allclose(cs[ok, 1], np.sin(np.deg2rad(h[ok])), atol=1e-12)
