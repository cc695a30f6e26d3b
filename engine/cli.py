"""Command line: ``python -m engine simulate | invert | process``.

Every option states its unit; errors in the input are reported on stderr with exit code 2.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from .chainage import GRID_STEP_M, PRODUCT_BAND_M
from .detect import DetectionConfig
from .direct import direct_inverse, filtered_direct_inverse
from .errors import EngineError, ParameterError
from .irregularity import SPECTRA, random_profile, read_profile_csv
from .logio import (
    GRAVITY_MODES,
    OPTION_UNITS,
    ROLE_LABELS,
    CsvOptions,
    read_run_csv,
    write_run_csv,
)
from .pipeline import METHODS, ProcessConfig, RunSetup, prepare_run, process_run
from .runlog import RunLog
from .sensor import SENSOR_GRADES, SensorModel, sensor_for_grade
from .simulate import simulate
from .synthetic import to_runlog
from .track import SoftZone, Track, TrackParams
from .vehicle import PRESETS, TABLE1, VehicleParams, get_preset

TRACK_HELP = {
    "spacing": "support (sleeper) spacing, m", "EI": "rail bending stiffness, N m^2",
    "mass_per_m": "rail mass, kg/m", "k_nominal": "nominal support stiffness, N/m",
    "c_support": "support damping, N s/m",
}  # fmt: skip


def _add_vehicle(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group(
        "vehicle (default: the paper's Table 1; a preset, then single parameters override it)"
    )
    g.add_argument(
        "--vehicle",
        choices=sorted(PRESETS),
        default="table1",
        help="vehicle preset (default table1; heavy: about twice the wheel load)",
    )
    for f in fields(VehicleParams):
        dflt = f"table1 {getattr(TABLE1, f.name):g}"
        g.add_argument(
            f"--{f.name}",
            type=float,
            default=None,
            metavar="X",
            help=f"{f.metadata['description'].lower()}, {f.metadata['unit']} "
            f"(default: the preset's; {dflt})",
        )


def _add_track(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("track (default: UIC60 on 80 kN/mm supports every 0.6 m)")
    defaults = TrackParams()
    for f in fields(TrackParams):
        g.add_argument(
            f"--{f.name.replace('_', '-')}",
            dest=f"track_{f.name}",
            type=float,
            default=None,
            metavar="X",
            help=f"{TRACK_HELP[f.name]} (default {getattr(defaults, f.name):g})",
        )


def _add_direction(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--direction",
        choices=["increasing", "decreasing"],
        default="increasing",
        help="direction of travel along chainage (default increasing)",
    )


def _add_run(p: argparse.ArgumentParser) -> None:
    """The run log to read and where it starts."""
    p.add_argument("run", help="run CSV")
    p.add_argument(
        "--start-chainage", type=float, default=None, help="body-centre chainage at start, m"
    )
    _add_direction(p)


def _add_band(p: argparse.ArgumentParser) -> None:
    """The wavelength band of the levels."""
    lo, hi = PRODUCT_BAND_M
    p.add_argument("--lambda-min", type=float, default=lo, help="shortest wavelength, m")
    p.add_argument("--lambda-max", type=float, default=hi, help="longest wavelength, m")


def _add_columns(p: argparse.ArgumentParser) -> None:
    # one option per CsvOptions field, choices from the reader's own unit lists
    g = p.add_argument_group(
        "columns and units of the input CSV (default: recognised from the header)"
    )
    for f in fields(CsvOptions):
        flag = "--" + f.name.replace("_", "-")
        if f.name == "gravity":
            g.add_argument(
                flag, choices=GRAVITY_MODES, default="auto",
                help="whether the acceleration includes gravity (+1 g at rest); default auto",
            )  # fmt: skip
            continue
        role, kind = f.name.rsplit("_", 1)
        if kind == "column":
            g.add_argument(flag, help=f"name of the {ROLE_LABELS[role]} column")
        else:
            g.add_argument(
                flag, choices=OPTION_UNITS[role], help=f"unit of the {ROLE_LABELS[role]}"
            )


def _vehicle(ns: argparse.Namespace) -> VehicleParams:
    base = get_preset(ns.vehicle).to_dict()
    over = {f.name: getattr(ns, f.name) for f in fields(VehicleParams)}
    base.update({k: v for k, v in over.items() if v is not None})
    return VehicleParams(**base)


def _track_params(ns: argparse.Namespace) -> TrackParams:
    over = {f.name: getattr(ns, f"track_{f.name}") for f in fields(TrackParams)}
    return TrackParams(**{k: v for k, v in over.items() if v is not None})


def _read_log(ns: argparse.Namespace) -> RunLog:
    opts = CsvOptions(**{f.name: getattr(ns, f.name) for f in fields(CsvOptions)})
    return read_run_csv(Path(ns.run), opts)


def _cmd_simulate(ns: argparse.Namespace) -> int:
    params = _track_params(ns)
    zones = tuple(SoftZone.parse(z) for z in ns.zone)
    track = Track(ns.length, params=params, zones=zones)
    if ns.jitter > 0:
        rng = np.random.default_rng(ns.seed)
        k = track.k * np.clip(1.0 + ns.jitter * rng.standard_normal(track.n_supports), 0.5, 1.5)
        track = Track(ns.length, params=params, support_stiffness=k, zones=zones)
    if ns.irregularity and ns.spectrum:
        raise EngineError("give either --irregularity (a CSV profile) or --spectrum, not both")
    prof = None
    if ns.irregularity:
        prof = read_profile_csv(ns.irregularity)
    elif ns.spectrum:
        prof = random_profile(
            ns.spectrum, ns.length, seed=ns.irregularity_seed, scale=ns.irregularity_scale
        )
    if prof is not None:
        track = Track(
            ns.length, params=params, support_stiffness=track.k, zones=zones,
            irregularity=prof.as_irregularity(),
        )  # fmt: skip
    speed: float | object = ns.speed
    if ns.speed_end is not None:
        if ns.duration is None:
            raise EngineError("--speed-end needs --duration (s)")
        v0, v1, T = ns.speed, ns.speed_end, ns.duration

        def speed(t: np.ndarray) -> np.ndarray:
            return v0 + (v1 - v0) * np.clip(t / T, 0.0, 1.0)

    sim = simulate(
        track,
        vehicle=_vehicle(ns),
        speed=speed,  # type: ignore[arg-type]
        duration=ns.duration,
        start_chainage_m=ns.start_chainage,
        dt=ns.dt,
        direction=ns.direction,
    )
    if ns.sensor_grade is not None:
        typed = [
            f for f in ("accel_noise", "gyro_noise", "accel_bias", "gyro_bias") if getattr(ns, f)
        ]
        if typed:
            raise ParameterError(
                f"--sensor-grade replaces the sensor figures: drop --{typed[0].replace('_', '-')}",
                field="sensor_grade",
            )
        sensor = sensor_for_grade(
            ns.sensor_grade, ns.rate or 1.0 / ns.dt, seed=ns.seed,
            digits=8 if ns.digits is None else ns.digits,
        )  # fmt: skip
    else:
        sensor = SensorModel(
            accel_noise=ns.accel_noise,
            gyro_noise=ns.gyro_noise,
            accel_bias=ns.accel_bias,
            gyro_bias=ns.gyro_bias,
            sample_rate_hz=ns.rate,
            digits=ns.digits,
        )
    log = to_runlog(sim, sensor, seed=ns.seed, chainage=ns.with_chainage)
    write_run_csv(log, Path(ns.out))
    if ns.truth:
        step = max(1, int(round(log.dt / sim.dt)))
        idx = np.arange(0, sim.t.size, step)
        _write_levels(
            ns.truth, sim.t[idx], sim.x_front[idx], sim.y_front[idx], sim.x_rear[idx],
            sim.y_rear[idx],
        )  # fmt: skip
    print(f"wrote {log.n} samples ({log.duration_s:.2f} s) to {ns.out}", file=sys.stderr)
    return 0


def _write_levels(
    dest: str,
    t: np.ndarray,
    x_front: np.ndarray,
    y_front: np.ndarray,
    x_rear: np.ndarray,
    y_rear: np.ndarray,
) -> None:
    """Levels CSV: time (s), chainage (m) and level (m in, mm out) of each axle."""
    np.savetxt(
        dest,
        np.column_stack([t, x_front, y_front * 1e3, x_rear, y_rear * 1e3]),
        delimiter=",",
        fmt="%.12g",
        header="time_s,front_chainage_m,front_level_mm,rear_chainage_m,rear_level_mm",
        comments="",
    )


def _cmd_invert(ns: argparse.Namespace) -> int:
    from .chainage import axle_positions

    log = _read_log(ns)
    vehicle = _vehicle(ns)
    pos = axle_positions(log, vehicle, ns.start_chainage, ns.direction)
    a, q, dt = log.accel_z_mps2, log.pitch_rate_radps, log.dt
    if ns.method == "direct":
        res = direct_inverse(a, q, dt, vehicle, gamma=ns.gamma, beta=ns.beta)
        y1, y2 = res.y_front, res.y_rear
    else:
        from .spectral import spectral_inverse

        cfg = ProcessConfig(lambda_min_m=ns.lambda_min, lambda_max_m=ns.lambda_max)
        # the band is the pipeline's (prepare_run: speed percentiles), so both invert alike
        setup = RunSetup(ns.start_chainage, ns.direction, vehicle, config=cfg)
        chk = prepare_run(log, setup, log_checked=True)  # read_run_csv checked it
        f_lo, f_hi = chk.f_lo_hz, chk.f_hi_hz
        if ns.method == "filtered-direct":
            fres = filtered_direct_inverse(a, q, dt, vehicle, f_lo, f_hi)
            y1, y2 = fres.y_front, fres.y_rear
        else:
            inv = spectral_inverse(a, q, dt, vehicle, f_lo, f_hi)
            y1, y2 = inv.y_front - inv.y_front[0], inv.y_rear - inv.y_rear[0]
    _write_levels(ns.out, log.time_s, pos.front, y1, pos.rear, y2)
    print(f"wrote {log.n} rows to {ns.out}", file=sys.stderr)
    return 0


def _cmd_process(ns: argparse.Namespace) -> int:
    log = _read_log(ns)
    det = DetectionConfig(
        baseline_window_m=ns.baseline_window,
        min_depth_mm=ns.min_depth,
        noise_factor=ns.noise_factor,
        min_length_m=ns.min_length,
    )
    cfg = ProcessConfig(
        method=ns.method,
        lambda_min_m=ns.lambda_min,
        lambda_max_m=ns.lambda_max,
        grid_step_m=ns.grid_step,
        detection=det,
    )
    setup = RunSetup(ns.start_chainage, ns.direction, _vehicle(ns), _track_params(ns), cfg)
    res = process_run(prepare_run(log, setup, log_checked=True))  # read_run_csv checked it
    out = Path(ns.out)
    out.mkdir(parents=True, exist_ok=True)
    ok = np.isfinite(res.level_mm)
    np.savetxt(
        out / "profile.csv",
        np.column_stack([res.chainage_m[ok], res.level_mm[ok]]),
        delimiter=",",
        fmt=["%.3f", "%.6f"],
        header="chainage_m,level_mm",
        comments="",
    )
    (out / "soft_spots.json").write_text(
        json.dumps([s.to_dict() for s in res.soft_spots], indent=1) + "\n"
    )
    (out / "quality.json").write_text(json.dumps(res.quality.to_dict(), indent=1) + "\n")
    if res.detection_limit is not None:
        (out / "detection_limit.json").write_text(
            json.dumps(res.detection_limit.to_dict(), indent=1) + "\n"
        )
    print(
        f"{ok.sum()} profile points, {len(res.soft_spots)} soft spot(s) written to {out}",
        file=sys.stderr,
    )
    return 0


def _simulate_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--length", type=float, default=200.0, help="track length, m (default 200)")
    p.add_argument("--speed", type=float, default=20.0, help="speed, m/s (default 20)")
    p.add_argument(
        "--speed-end", type=float, default=None, help="speed at the end, m/s: linear ramp"
    )
    p.add_argument(
        "--start-chainage",
        type=float,
        default=24.13,
        help="chainage of the body centre at t=0, m (default 24.13)",
    )
    p.add_argument(
        "--duration", type=float, default=None, help="duration, s (default: to the track end)"
    )
    _add_direction(p)
    p.add_argument(
        "--zone",
        action="append",
        default=[],
        metavar="START:END:LOSS",
        help="soft zone: first and last support chainage (m) and stiffness loss (fraction), "
        "e.g. 60:65:0.5; repeatable",
    )
    p.add_argument(
        "--jitter",
        type=float,
        default=0.0,
        help="support stiffness scatter, standard deviation as a fraction (e.g. 0.05)",
    )
    p.add_argument(
        "--irregularity",
        help="CSV with header and columns chainage_m,level_mm: unloaded rail irregularity",
    )
    p.add_argument(
        "--spectrum",
        choices=sorted(SPECTRA),
        default=None,
        help="unloaded rail irregularity drawn from a standard spectrum (1-120 m wavelengths; "
        "see docs/method.md)",
    )
    p.add_argument(
        "--irregularity-seed", type=int, default=0, help="seed of the --spectrum profile (0)"
    )
    p.add_argument(
        "--irregularity-scale",
        type=float,
        default=1.0,
        help="amplitude multiplier of the --spectrum profile (default 1)",
    )
    p.add_argument("--dt", type=float, default=1e-3, help="simulation time step, s (0.001)")
    p.add_argument("--rate", type=float, default=None, help="output sample rate, Hz")
    p.add_argument("--accel-noise", type=float, default=0.0, help="accel noise sigma, m/s^2")
    p.add_argument("--gyro-noise", type=float, default=0.0, help="gyro noise sigma, rad/s")
    p.add_argument("--accel-bias", type=float, default=0.0, help="accel bias, m/s^2")
    p.add_argument("--gyro-bias", type=float, default=0.0, help="gyro bias, rad/s")
    p.add_argument("--digits", type=int, default=None, help="significant digits written")
    p.add_argument(
        "--sensor-grade",
        choices=tuple(SENSOR_GRADES),
        default=None,
        help="an IMU class instead of the noise/bias figures (densities over the output "
        "band, per-pass bias from --seed, wander, quantisation, jitter; docs/sensors.md)",
    )
    p.add_argument("--seed", type=int, default=None, help="random seed (noise, jitter)")
    p.add_argument("--with-chainage", action="store_true", help="also write a chainage_m column, m")
    p.add_argument("--out", required=True, help="output run CSV")
    p.add_argument(
        "--truth",
        help="also write the true loaded levels (mm, absolute, positive up) under each axle",
    )
    _add_track(p)


def _invert_arguments(p: argparse.ArgumentParser) -> None:
    _add_run(p)
    p.add_argument(
        "--method",
        choices=["spectral", "filtered-direct", "direct"],
        default="spectral",
        help="direct: the paper's integration (exact on noise-free Newmark data only); "
        "spectral: band-limited inversion (default); filtered-direct: band-passed inputs "
        "then dissipative direct integration",
    )
    p.add_argument("--gamma", type=float, default=0.5, help="Newmark gamma (direct)")
    p.add_argument("--beta", type=float, default=0.25, help="Newmark beta (direct)")
    _add_band(p)
    p.add_argument("--out", required=True, help="output levels CSV")
    _add_columns(p)


def _process_arguments(p: argparse.ArgumentParser) -> None:
    _add_run(p)
    p.add_argument(
        "--method",
        choices=list(METHODS),
        default=next(iter(METHODS)),
        help=f"inversion method (default {next(iter(METHODS))}; see docs/method.md)",
    )
    _add_band(p)
    p.add_argument("--grid-step", type=float, default=GRID_STEP_M, help="chainage grid step, m")
    d = DetectionConfig()
    p.add_argument(
        "--baseline-window", type=float, default=d.baseline_window_m, help="baseline median, m"
    )
    p.add_argument(
        "--min-depth", type=float, default=d.min_depth_mm, help="smallest dip reported, mm"
    )
    p.add_argument(
        "--noise-factor", type=float, default=d.noise_factor, help="threshold in noise sigmas"
    )
    p.add_argument(
        "--min-length", type=float, default=d.min_length_m, help="shortest dip reported, m"
    )
    p.add_argument("--out", required=True, help="output directory")
    _add_columns(p)
    _add_track(p)


@dataclass(frozen=True)
class _Command:
    """A subcommand: its one-line help, its description, its own options and what runs it."""

    help: str
    description: str
    arguments: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int]


_COMMANDS = {
    "simulate": _Command(
        help="forward-simulate a run and write its log CSV",
        description="Coupled vehicle-track simulation (Newmark-beta) written as a canonical "
        "run CSV (time_s, accel_z_mps2, pitch_rate_radps, speed_mps).",
        arguments=_simulate_arguments,
        run=_cmd_simulate,
    ),
    "invert": _Command(
        help="levels under each axle against time",
        description="Invert a run log to the loaded level under each axle; writes time_s, "
        "front_chainage_m, front_level_mm, rear_chainage_m, rear_level_mm (mm relative to the "
        "first sample, positive up).",
        arguments=_invert_arguments,
        run=_cmd_invert,
    ),
    "process": _Command(
        help="fused profile on chainage and soft spots",
        description="Invert, fuse both axles on a chainage grid, detect soft spots and "
        "estimate stiffness loss. Writes DIR/profile.csv (chainage_m,level_mm), "
        "DIR/soft_spots.json and DIR/quality.json.",
        arguments=_process_arguments,
        run=_cmd_process,
    ),
}


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``python -m engine``."""
    p = argparse.ArgumentParser(
        prog="python -m engine",
        description="Drive-by track monitoring engine: simulate runs, invert logs to loaded "
        "track profiles, find soft spots.",
    )
    sub = p.add_subparsers(dest="command", required=True)
    for name, cmd in _COMMANDS.items():
        sp = sub.add_parser(name, help=cmd.help, description=cmd.description)
        cmd.arguments(sp)
        # every command simulates or inverts with a vehicle
        _add_vehicle(sp)
        sp.set_defaults(func=cmd.run)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``python -m engine``; returns the exit code."""
    parser = build_parser()
    ns = parser.parse_args(argv)
    try:
        return int(ns.func(ns))
    except EngineError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
