"""Mission plans from ground stations: QGroundControl .plan and Mission Planner .waypoints
(written here in the formats' published layouts), round trips and one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from aeromag.errors import InputError
from aeromag.io.plans import read_plan
from aeromag.track import check_track

HOME = (47.3977419, 8.545594, 487.989)   # lat, lon, alt above mean sea level
WAYPOINTS = [(47.3985099, 8.5451002, 50.0), (47.3990000, 8.5460000, 55.0),
             (47.3995000, 8.5450000, 60.0)]


def _simple(command: int, lat: float, lon: float, alt: float, frame: int = 3,
            jump: int = 1, p1: float = 0.0) -> dict:
    return {"AMSLAltAboveTerrain": None, "Altitude": alt, "AltitudeMode": 1,
            "autoContinue": True, "command": command, "doJumpId": jump, "frame": frame,
            "params": [p1, 0, 0, None, lat, lon, alt], "type": "SimpleItem"}


def qgc_plan(items: list[dict], home=HOME) -> dict:
    """A QGroundControl plan document (https://docs.qgroundcontrol.com, Plan File Format)."""
    return {"fileType": "Plan", "geoFence": {"circles": [], "polygons": [], "version": 2},
            "groundStation": "QGroundControl",
            "mission": {"cruiseSpeed": 15, "firmwareType": 12, "globalPlanAltitudeMode": 1,
                        "hoverSpeed": 5, "items": items, "plannedHomePosition": list(home),
                        "vehicleType": 2, "version": 2},
            "rallyPoints": {"points": [], "version": 2}, "version": 1}


def _standard_items() -> list[dict]:
    """Take-off, a speed change, the three waypoints with a delay between, then landing."""
    w = WAYPOINTS
    return [
        _simple(22, HOME[0], HOME[1], 30.0, jump=1, p1=15),            # take-off
        _simple(178, 0, 0, 0, frame=2, jump=2, p1=1) | {"params": [1, 5, -1, 0, 0, 0, 0]},
        _simple(16, *w[0], jump=3),
        _simple(93, 0, 0, 0, frame=2, jump=4) | {"params": [5, -1, -1, -1, 0, 0, 0]},  # delay
        _simple(16, *w[1], jump=5),
        _simple(16, *w[2], jump=6),
        _simple(21, HOME[0], HOME[1], 0.0, jump=7),                    # land
    ]


def waypoints_text(rows: list[tuple], header: str = "QGC WPL 110") -> str:
    """A Mission Planner / ArduPilot mission (mavlink.io, Mission Plain-Text File Format)."""
    lines = [header]
    for r in rows:
        lines.append("\t".join(str(v) for v in r))
    return "\n".join(lines) + "\n"


def _standard_rows() -> list[tuple]:
    w = WAYPOINTS
    return [
        (0, 1, 0, 16, 0, 0, 0, 0, HOME[0], HOME[1], HOME[2], 1),            # home
        (1, 0, 3, 22, 15, 0, 0, 0, 0, 0, 30, 1),                              # take-off
        (2, 0, 3, 16, 0, 0, 0, 0, w[0][0], w[0][1], w[0][2], 1),
        (3, 0, 3, 178, 1, 5, -1, 0, 0, 0, 0, 1),                              # speed
        (4, 0, 3, 93, 5, -1, -1, -1, 0, 0, 0, 1),                             # delay
        (5, 0, 3, 16, 0, 0, 0, 0, w[1][0], w[1][1], w[1][2], 1),
        (6, 0, 0, 16, 0, 0, 0, 0, w[2][0], w[2][1], HOME[2] + w[2][2], 1),   # absolute frame
        (7, 0, 3, 21, 0, 0, 0, 0, HOME[0], HOME[1], 0, 1),                    # land
    ]


def _expected() -> np.ndarray:
    return np.array([(la, lo, HOME[2] + a) for la, lo, a in WAYPOINTS])


def test_qgc_plan_round_trip(tmp_path):
    p = tmp_path / "mission.plan"
    p.write_text(json.dumps(qgc_plan(_standard_items()), indent=4))
    plan = read_plan(p)
    np.testing.assert_allclose(plan[["lat", "lon", "alt"]].to_numpy(), _expected(), atol=1e-9)
    assert plan.attrs["format"] == "qgc-plan" and plan.attrs["home_alt"] == HOME[2]
    text = p.read_text().splitlines()
    for line in plan.attrs["lines"]:     # each waypoint's line holds its doJumpId
        assert '"doJumpId"' in text[line - 1]


def test_qgc_survey_complex_item(tmp_path):
    inner = [_simple(16, *WAYPOINTS[1], jump=3), _simple(206, 0, 0, 0, frame=2, jump=4),
             _simple(16, *WAYPOINTS[2], jump=5)]
    survey = {"type": "ComplexItem", "complexItemType": "survey", "version": 5,
              "TransectStyleComplexItem": {"Items": inner, "VisualTransectPoints": []},
              "polygon": []}
    p = tmp_path / "survey.plan"
    p.write_text(json.dumps(qgc_plan([_simple(22, *HOME[:2], 30.0, jump=1),
                                      _simple(16, *WAYPOINTS[0], jump=2), survey])))
    plan = read_plan(p)
    np.testing.assert_allclose(plan[["lat", "lon", "alt"]].to_numpy(), _expected(), atol=1e-9)


def test_waypoints_round_trip(tmp_path):
    p = tmp_path / "mission.waypoints"
    p.write_text(waypoints_text(_standard_rows()))
    plan = read_plan(p)
    np.testing.assert_allclose(plan[["lat", "lon", "alt"]].to_numpy(), _expected(), atol=1e-9)
    assert plan.attrs["format"] == "qgc-wpl" and plan.attrs["lines"] == [4, 7, 8]
    # a CSV written from it reads back the same
    csv = tmp_path / "plan.csv"
    plan[["lat", "lon", "alt"]].to_csv(csv, index=False)
    pd.testing.assert_frame_equal(read_plan(csv)[["lat", "lon", "alt"]],
                                  plan[["lat", "lon", "alt"]].reset_index(drop=True))


@pytest.mark.parametrize(("rows_edit", "match"), [
    (lambda r: r[:2], "0 navigation waypoint"),
    (lambda r: r[:3] + [(3, 0, 3, 16, 0, 0, 0, 0, "x", 8.5, 50, 1)], "line 5: latitude"),
    (lambda r: r[:3] + [(3, 0, 3, 16, 0, 0, 0, 0, 47.4)], "line 5: 9 field"),
    (lambda r: r[:3] + [(5, 0, 3, 16, 0, 0, 0, 0, 47.4, 8.5, 50, 1)], "line 5: item index 5"),
    (lambda r: r[:3] + [(3, 0, 10, 16, 0, 0, 0, 0, 47.4, 8.5, 50, 1)], "above terrain"),
    (lambda r: r[:3] + [(3, 0, 1, 16, 0, 0, 0, 0, 47.4, 8.5, 50, 1)], "not a global frame"),
    (lambda r: r[:3] + [(3, 0, 3, 16, 0, 0, 0, 0, 147.4, 8.5, 50, 1)], "line 5.: latitude 147"),
    (lambda r: r[:3] + [r[2][:0] + (3,) + r[2][1:]], "lines 4 and 5: repeated waypoint"),
])
def test_bad_waypoints_files(tmp_path, rows_edit, match):
    p = tmp_path / "bad.waypoints"
    p.write_text(waypoints_text(rows_edit(_standard_rows())))
    with pytest.raises(InputError, match=match) as err:
        read_plan(p)
    msg = str(err.value)
    assert msg.startswith(str(p)) and "\n" not in msg


def test_bad_headers_and_documents(tmp_path):
    cases = {
        "a.waypoints": ("QGC WPL 120\n0\t1\t0\t16\t0\t0\t0\t0\t1\t2\t3\t1\n", "only version 110"),
        "b.waypoints": ("lat,lon,alt\n1,2,3\n", "line 1: expected the header"),
        "c.plan": ('{"fileType": "Plan", "mission": {"items": [}', "line 1: not valid JSON"),
        "d.plan": ('{"fileType": "Geofence"}', "not a QGroundControl plan"),
        "e.plan": (json.dumps(qgc_plan([{"type": "Banana"}])), "item 1: unknown item type"),
        "f.plan": (json.dumps(qgc_plan([_simple(16, *WAYPOINTS[0]), _simple(16, *WAYPOINTS[1])],
                                       home=[])), "no home altitude"),
        "g.plan": (json.dumps(qgc_plan([_simple(16, *WAYPOINTS[0]),
                                        _simple(16, 47.4, "8.5", 50.0, jump=2)], )),
                   "item 2 \\(line \\d+\\): longitude"),
        "h.plan": (json.dumps(qgc_plan([{"type": "ComplexItem",
                                         "complexItemType": "structureScan"}])),
                   "export the mission as .waypoints"),
        "i.waypoints": (b"QGC WPL 110\n\xff\xfe\n", "line 2: not UTF-8"),
    }
    for name, (text, match) in cases.items():
        p = tmp_path / name
        if isinstance(text, bytes):
            p.write_bytes(text)
        else:
            p.write_text(text)
        with pytest.raises(InputError, match=match) as err:
            read_plan(p)
        assert str(err.value).startswith(str(p)) and "\n" not in str(err.value), name


def test_a_ground_station_plan_checks_a_flight(tmp_path):
    """A .waypoints plan (altitudes above mean sea level) against a log on the ellipsoid: the
    geoid undulation is found as a constant offset, reported and removed."""
    from aeromag.synthetic.mission import simulate_mission

    df, plan_csv, truth = simulate_mission(seed=3, line_m=150.0, n_lines=2)
    undulation = 48.3
    rows = [(0, 1, 0, 16, 0, 0, 0, 0, plan_csv["lat"][0], plan_csv["lon"][0],
             plan_csv["alt"][0] - 40.0 - undulation, 1),
            (1, 0, 3, 22, 0, 0, 0, 0, 0, 0, 40.0, 1)]
    for i, r in plan_csv.iterrows():
        rel = r["alt"] - plan_csv["alt"][0] + 40.0   # relative to home
        rows.append((i + 2, 0, 3, 16, 0, 0, 0, 0, r["lat"], r["lon"], rel, 1))
    p = tmp_path / "m.waypoints"
    p.write_text(waypoints_text(rows))
    plan = read_plan(p)
    np.testing.assert_allclose(plan["alt"], plan_csv["alt"] - undulation, atol=1e-6)
    res = check_track(df, plan)
    off = res.report.altitude_offset
    assert off["applied_m"] == pytest.approx(undulation, abs=0.05)
    assert any("altitude reference" in w for w in res.report.warnings)
    ref = check_track(df, plan_csv)
    assert res.report.flagged_legs == ref.report.flagged_legs
    np.testing.assert_allclose(res.data["xtrack_m"], ref.data["xtrack_m"], atol=0.06)


def test_cli_reads_plan_files(tmp_path):
    from aeromag.workflows.mission import write_mission_files

    paths = write_mission_files(tmp_path, seed=0, line_m=120.0, n_lines=2)
    plan = pd.read_csv(paths["plan"])
    doc = qgc_plan([_simple(16, r["lat"], r["lon"], r["alt"], frame=0, jump=i + 1)
                    for i, r in plan.iterrows()])
    qp = tmp_path / "m.plan"
    qp.write_text(json.dumps(doc))
    out = tmp_path / "out.csv"
    res = subprocess.run([sys.executable, "-m", "aeromag", "track", str(paths["mission"]),
                          "--plan", str(qp), "-o", str(out)], capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr
    rep = json.loads(out.with_suffix(".json").read_text())
    assert rep["plan_format"] == "qgc-plan" and rep["n_legs"] == len(plan) - 1
    bad = tmp_path / "bad.plan"
    bad.write_text('{"fileType": "Plan"')
    res = subprocess.run([sys.executable, "-m", "aeromag", "track", str(paths["mission"]),
                          "--plan", str(bad), "-o", str(tmp_path / "o2.csv")],
                         capture_output=True, text=True, timeout=300)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 1 and len(lines) == 1 and lines[0].startswith("error: ")
    assert str(bad) in lines[0] and not (tmp_path / "o2.csv").exists()
