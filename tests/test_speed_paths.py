"""Fast paths give what the simple computation gives (issue 17).

Each test compares a vectorised or shortcut path with the plain computation it replaces, or
checks that a start-up shortcut leaves the library as it found it.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from aeromag._core import filters
from aeromag.qc.fom import _box_entries
from aeromag.qc.maneuvers import CARDINALS, MANEUVERS


def _stretches(rng: np.random.Generator, n: int) -> np.ndarray:
    """Stretch labels: runs of a few lengths (some too short to filter), gaps between."""
    lab = np.full(n, -1, dtype=np.int64)
    i, k = 0, 0
    while i < n:
        L = int(rng.choice([5, 40, 300, 300, 300, 450, 2000]))
        lab[i:i + L] = k
        i += L + int(rng.integers(0, 3))
        k += 1
    return lab


@pytest.mark.parametrize("axis", [0, 1])
def test_filter_stretches_stacked_equals_one_by_one(axis: int, monkeypatch) -> None:
    rng = np.random.default_rng(17)
    n = 60_000
    lab = _stretches(rng, n)
    x = rng.normal(size=(3, n)).cumsum(axis=1)
    x[1, 12_345] = np.nan  # one stretch of row 1 not finite: that stretch NaN in every row
    xa = x if axis == 1 else x.T.copy()
    sos = filters.butter_sos("bandpass", (0.1, 0.9), 10.0, 4)
    fast = filters.filter_stretches(xa, lab, sos, axis=axis)
    monkeypatch.setattr(filters, "_MIN_BATCHED_STRETCHES", 10**9)  # the plain loop
    plain = filters.filter_stretches(xa, lab, sos, axis=axis)
    assert np.isnan(plain).any()
    np.testing.assert_array_equal(fast, plain)  # bitwise, NaN where NaN


def _box_entries_groupby(table: pd.DataFrame, cols: list[str]) -> list[dict]:
    """The per-box entries through a pandas groupby (the code fom_summary had)."""
    boxes = []
    for b, g in table.groupby("box"):
        pairs = set(zip(g["heading_leg"], g["maneuver"], strict=True))
        missing = [f"{CARDINALS[h]} {m}" for h in range(4) for m in MANEUVERS
                   if (h, m) not in pairs]
        e: dict = {"box": int(b), "n_maneuvers": len(g), "complete": not missing,
                             "missing": missing}
        for c in cols:
            e[f"fom_{c}_nT"] = float(np.nansum(g[f"ptp_{c}_nT"])) if not missing else None
        if "kept" in g.columns:
            gk = g[g["kept"].to_numpy(dtype=bool)]
            e["n_maneuvers_kept"] = len(gk)
            e["dropped"] = [f"{CARDINALS[int(h)]} {m}" for h, m in
                            zip(g["heading_leg"][~g["kept"].to_numpy(dtype=bool)],
                                g["maneuver"][~g["kept"].to_numpy(dtype=bool)], strict=True)]
            for c in cols:
                e[f"fom_kept_{c}_nT"] = (float(np.nansum(gk[f"ptp_{c}_nT"]))
                                         if not missing else None)
        boxes.append(e)
    return boxes


def test_fom_box_entries_equal_groupby() -> None:
    rng = np.random.default_rng(3)
    rows = []
    for b in rng.permutation(40):  # boxes out of order; some incomplete, some with extras
        for h in range(4):
            for m in MANEUVERS:
                if rng.random() < 0.08:
                    continue
                for _ in range(1 + int(rng.random() < 0.1)):
                    rows.append((int(b), h, m))
    rng.shuffle(rows)
    table = pd.DataFrame(rows, columns=["box", "heading_leg", "maneuver"])
    for c in ("before", "after", "truth"):
        v = rng.lognormal(size=len(table)) * 10 ** rng.uniform(-3, 3, len(table))
        v[rng.random(len(v)) < 0.05] = np.nan
        table[f"ptp_{c}_nT"] = v
    table["kept"] = rng.random(len(table)) > 0.2
    table.attrs["fields"] = {"before": "mag"}
    cols = ["before", "after", "truth"]
    def entries(t: pd.DataFrame, c: list[str]) -> list[dict]:
        return [e.to_dict() for e in _box_entries(t, c)]

    assert entries(table, cols) == _box_entries_groupby(table, cols)  # exact floats
    assert entries(table.drop(columns="kept"), cols[:2]) == \
        _box_entries_groupby(table.drop(columns="kept"), cols[:2])
    assert _box_entries(table.iloc[:0], cols) == []


def test_json_layout_parses_to_the_same_document(tmp_path) -> None:
    import json

    from aeromag.io.json import dumps_readable, write_json

    doc = {"a": 1, "b": [1.5, None, "x"], "c": {}, "d": [], "e": {"f": {"g": [True, False]}},
           "segments": [{"id": i, "pca": [0.1 * i, float("nan")], "kept": i % 2 == 0,
                         "name": f"seg {i}"} for i in range(5)],
           "rows": [[1, 2], [3, [4, {"z": np.float64(2.5)}]], ()],
           "np": {"i": np.int64(3), "f": np.float32(0.5), "b": np.bool_(True),
                  "arr": np.array([[1.0, np.inf], [2.0, 3.0]])},
           7: "int key", "u": "é\n\"q\""}
    path = write_json(doc, tmp_path / "x.json")
    text = path.read_text(encoding="utf-8")
    got = json.loads(text)
    ref = json.loads(json.dumps(_jsonable_ref(doc), indent=2, default=_default_ref))
    assert got == ref
    # one segment per line, keys of dicts outside lists one per line
    lines = text.splitlines()
    assert sum(line.strip().startswith('{"id": ') for line in lines) == 5
    assert '  "a": 1,' in lines
    assert dumps_readable([]) == "[]" and dumps_readable({}) == "{}"
    assert json.loads(dumps_readable((1, [2, {"k": (3,)}]))) == [1, [2, {"k": [3]}]]


def _jsonable_ref(obj):
    """The old path's NaN handling (aeromag.io.json._jsonable)."""
    from aeromag.io.json import _jsonable

    return _jsonable(obj)


def _default_ref(obj):
    from aeromag.io.json import _json_default

    return _json_default(obj)


def test_qc_concurrent_equals_serial(monkeypatch) -> None:
    """compute_qc's residuals and noise on the pool give the serial run's metrics exactly."""
    from aeromag._core import parallel
    from aeromag.compensation.pipeline import run_compensation as compensate
    from aeromag.qc import compute_qc
    from aeromag.synthetic import simulate_calibration

    df, _ = simulate_calibration(seed=5, n_boxes=1)
    res = compensate(df)
    threaded = compute_qc(res, fit=False, fom=True).metrics
    monkeypatch.setattr(parallel, "THREADS", 1)  # submit() runs inline
    serial = compute_qc(res, fit=False, fom=True).metrics
    assert threaded == serial
    assert threaded.fom.applicable
    broken = res.data[["time", "mag", "mag_comp", "mag_tl"]]  # nothing to detect from
    notes = compute_qc(type(res)(broken, None, {}), fit=False, fom=True).metrics.notes
    assert any(n.startswith("manoeuvre detection failed") for n in notes)


def test_known_sampling_rate_gives_the_same_fom_and_maneuvers() -> None:
    from aeromag._core.filters import sampling_rate
    from aeromag.compensation.pipeline import run_compensation as compensate
    from aeromag.qc import detect_maneuvers, fom_table
    from aeromag.synthetic import simulate_calibration

    df, _ = simulate_calibration(seed=6, n_boxes=1)
    data = compensate(df).data
    fs = sampling_rate(data["time"].to_numpy())
    m0, m1 = detect_maneuvers(data), detect_maneuvers(data, fs_hz=fs)
    pd.testing.assert_frame_equal(m0.table, m1.table)
    pd.testing.assert_frame_equal(m0.labels, m1.labels)
    pd.testing.assert_frame_equal(fom_table(data, m0), fom_table(data, m0, fs_hz=fs))


def test_clip_to_lines_shallow_copy_leaves_the_input_labels() -> None:
    from aeromag.qc._lines import clip_to_lines
    from aeromag.qc.maneuvers import ManeuverResult

    t = np.arange(100) * 0.1
    line = np.where(t < 3.0, 1, 2)
    mid = np.where(t < 9.0, 0, -1)
    lab = pd.DataFrame({"heading_leg": 0, "leg_id": 0, "box": 0, "maneuver_id": mid})
    lab["maneuver"] = pd.Categorical.from_codes(np.where(mid == 0, 2, 0),
                                                categories=["", *MANEUVERS])
    before = lab.copy()
    tab = pd.DataFrame({"id": [0], "box": [0], "heading_leg": [0], "heading": ["N"],
                        "maneuver": ["roll"], "t_start": [0.0], "t_end": [8.9],
                        "duration_s": [9.0], "n": [90]})
    got = clip_to_lines(ManeuverResult(lab, tab, pd.DataFrame(), "column:maneuver"), line, t,
                        10.0)
    assert (got.labels["maneuver_id"].to_numpy()[t < 3.0] == -1).all()
    pd.testing.assert_frame_equal(lab, before)  # the input's columns are untouched
