"""``aeromag navigate``: inertial navigation aided by flow, range, baro, magnetometer, GNSS."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._app import app, column_options, setup_logging, user_errors
from ._progress import progress_bar

# The measurement models of aeromag.nav (literal so that 'aeromag --help' imports no numerics;
# a test checks it equals aeromag.nav.ALL_SENSORS).
SENSORS = ("gps_pos", "gps_vel", "range", "flow", "baro", "gravity", "mag")


#: NavConfig fields -> the options that set them (so an error names what the user typed).
_OPTION_OF_FIELD = {
    "gyro_noise_dps": "--gyro-noise", "accel_noise_g": "--accel-noise",
    "flow_noise_ms": "--flow-noise", "flow_min_quality": "--flow-min-quality",
    "range_noise_m": "--range-noise", "range_max_m must exceed range_min_m":
    "--range-limits MIN MAX: MAX must exceed MIN", "range_min_m": "--range-limits MIN",
    "range_max_m": "--range-limits MAX", "baro_noise_m": "--baro-noise",
    "mag_heading_noise_deg": "--mag-noise", "gps_cep_m": "--gps-cep",
    "gps_vel_noise_ms": "--gps-vel-noise", "max_tilt_deg": "--max-tilt",
    "max_imu_step_s": "--imu-step", "robust must": "--robust must",
    "flow_stamp must": "--flow-stamp must"}

@app.command()
def navigate(
    log_file: Annotated[Path, typer.Argument(metavar="LOG", help="Multi-rate log with time, "
                                             "gyro_x..z (rad/s), acc_x..z (m/s2) and any of "
                                             "flow_x/y, flow_quality, range_m, baro_alt, "
                                             "flux_x..z, lat/lon/alt, vel_n/e/d.",
                                             show_default=False)],
    output: Annotated[Path, typer.Option("-o", metavar="OUT.csv", help="Output CSV (the report "
                                         "goes to OUT.json).")],
    gps: Annotated[str, typer.Option("--gps", metavar="use|none|T0:T1",
                   help="Use GNSS; use only its first fix (to start); or withhold it between "
                   "T0 and T1 s (an outage).")] = "use",
    origin: Annotated[tuple[float, float, float] | None, typer.Option(
        "--origin", metavar="LAT LON ALT", help="Origin of the local frame when the log has no "
        "GNSS fix (degrees, degrees, m above the ellipsoid).")] = None,
    date: Annotated[str | None, typer.Option("--date", metavar="YYYY-MM-DD",
                    help="Flight date: the magnetic reference (and declination) is IGRF at "
                    "the first fix or --origin.")] = None,
    earth_field: Annotated[tuple[float, float, float] | None, typer.Option(
        "--earth-field", metavar="F I D", help="Explicit magnetic reference: intensity nT, "
        "inclination and declination degrees.")] = None,
    gyro_noise: Annotated[float, typer.Option("--gyro-noise", metavar="DPS",
                          help="Gyro white noise, rms per sample, deg/s.")] = 0.05,
    accel_noise: Annotated[float, typer.Option("--accel-noise", metavar="G",
                           help="Accelerometer white noise, rms per sample, g.")] = 0.05,
    accel_bias: Annotated[bool, typer.Option(
        "--accel-bias/--no-accel-bias",
        help="Estimate accelerometer biases (default; --no-accel-bias: the study's 12 states,"
             " overconfident in attitude on a real IMU).")] = True,
    flow_noise: Annotated[float, typer.Option("--flow-noise", metavar="M/S",
                          help="Optical-flow noise as a ground speed, m/s.")] = 0.01,
    flow_min_quality: Annotated[int, typer.Option("--flow-min-quality", metavar="Q",
                                help="Ignore flow samples of lower flow_quality (0-255).")] = 1,
    range_noise: Annotated[float, typer.Option("--range-noise", metavar="M",
                           help="Rangefinder noise, m.")] = 0.01,
    range_limits: Annotated[tuple[float, float], typer.Option(
        "--range-limits", metavar="MIN MAX", help="Valid rangefinder readings, m.")] = (0.3, 5.0),
    baro_noise: Annotated[float, typer.Option("--baro-noise", metavar="M",
                          help="Barometer noise, m.")] = 0.5,
    mag_noise: Annotated[float, typer.Option("--mag-noise", metavar="DEG",
                         help="Magnetometer heading noise, degrees.")] = 1.0,
    gps_cep: Annotated[float, typer.Option("--gps-cep", metavar="M",
                       help="GNSS horizontal accuracy (CEP), m.")] = 2.5,
    gps_vel_noise: Annotated[float, typer.Option("--gps-vel-noise", metavar="M/S",
                             help="GNSS velocity noise per axis, m/s.")] = 0.1,
    max_tilt: Annotated[float, typer.Option("--max-tilt", metavar="DEG",
                        help="No flow or range beyond this tilt, degrees.")] = 30.0,
    imu_step: Annotated[float, typer.Option("--imu-step", metavar="S",
                        help="Combine IMU samples into steps of at most S seconds (faster; 0: "
                        "every sample).")] = 0.0,
    robust: Annotated[str, typer.Option(
        "--robust", metavar="huber|none", help="Huber down-weighting of outlying innovations "
        "(default) or plain updates; only gross faults (8 sigma) are refused.")] = "huber",
    adaptive: Annotated[bool, typer.Option(
        "--adaptive-noise/--fixed-noise", help="Size each sensor's noise from its innovations "
        "(bounded; default) or keep the given noise figures.")] = True,
    flow_stamp: Annotated[str, typer.Option(
        "--flow-stamp", metavar="middle|end", help="Where the log stamps each flow sample in "
        "its integration interval (the interface: middle).")] = "middle",
    without: Annotated[list[str] | None, typer.Option(
        "--without", metavar="SENSOR", help="Leave a measurement out, repeatable: "
        + ", ".join(SENSORS) + ".")] = None,
    col: Annotated[list[str] | None, typer.Option("--col", metavar="NAME=SOURCE",
                   help="Column map, repeatable (e.g. gyro_x=IMU.GyrX).")] = None,
    map_file: Annotated[Path | None, typer.Option("--map", metavar="FILE",
                        help="TOML column map: [columns] NAME = \"SOURCE\", optional "
                        "[units] NAME = \"UNIT\".")] = None,
    units: Annotated[list[str] | None, typer.Option(
        "--units", metavar="NAME=UNIT", help="Convert a column or group: gyro or flow "
        "(deg/s), acc (g, mg), field columns or groups (to nT).")] = None,
    verbose: Annotated[bool, typer.Option("-v", "--verbose", help="Log progress details.")]
    = False,
) -> None:
    """Navigate: an unscented Kalman filter on IMU, flow, GNSS.

    Aiding: optical flow, rangefinder, barometer, gravity, magnetometer, GNSS.

    Writes OUT.csv (the log plus nav_lat, nav_lon, nav_alt, nav_n_m, nav_e_m, nav_d_m,
    nav_vn, nav_ve, nav_vd, nav_roll, nav_pitch, nav_yaw, nav_std_n_m, nav_std_e_m,
    nav_std_d_m at every row) and OUT.json (GNSS intervals used, settings, per-sensor
    normalised innovation squared).
    """
    setup_logging(verbose)
    from ..errors import InputError
    from ..io import json_path_for

    with user_errors(), progress_bar("aeromag navigate"):  # a bar on a terminal only
        bad = sorted(set(without or []) - set(SENSORS))
        if bad:
            raise InputError(f"--without {bad[0]}: unknown sensor; use one of "
                             f"{', '.join(SENSORS)}")
        from ..nav.config import NavConfig
        from ..workflows.navigate import navigate_file

        try:
            cfg = NavConfig(gyro_noise_dps=gyro_noise, accel_noise_g=accel_noise,
                            accel_bias=accel_bias, flow_noise_ms=flow_noise,
                            flow_min_quality=flow_min_quality, range_noise_m=range_noise,
                            range_min_m=range_limits[0], range_max_m=range_limits[1],
                            baro_noise_m=baro_noise, mag_heading_noise_deg=mag_noise,
                            gps_cep_m=gps_cep, gps_vel_noise_ms=gps_vel_noise,
                            max_tilt_deg=max_tilt, max_imu_step_s=imu_step, robust=robust,
                            adaptive_noise=adaptive, imu_noise_from_data=adaptive,
                            flow_stamp=flow_stamp)
        except ValueError as exc:
            msg = str(exc)
            for field, opt in _OPTION_OF_FIELD.items():
                msg = msg.replace(field, opt)
            raise InputError(f"navigate options: {msg}") from None
        columns, unit_map = column_options(col, map_file, units)
        sensors = [s for s in SENSORS if s not in set(without or [])]
        res = navigate_file(log_file, output, gps=gps, origin=origin, date=date,
                            earth_field=earth_field, config=cfg, sensors=sensors,
                            columns=columns, units=unit_map)
    rep = res.report
    nis = ", ".join(f"{k} {v / rep.innovations[k]['dof']:.2f}"
                    for k, v in rep.mean_nis.items() if v is not None)
    line = (f"wrote {output} and {json_path_for(output)}: {len(res.data)} rows; mean NIS/dof "
            f"{nis or 'none (no aiding fused)'}")
    if rep.warnings:
        line += f"; {len(rep.warnings)} warning(s) in {json_path_for(output).name}"
    typer.echo(line)
