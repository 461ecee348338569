"""``cosim tune ...``: trim, linearise, loop margins and gain tuning from the command line.

    tune trim AIRFRAME [--out DIR] [--no-check]       envelope trim: CSV, Markdown, PNG
    tune trim haps --eas 8 [--altitudes 0:23000:1000]  trims at one EAS from the ground up
    tune linearize AIRFRAME [--alt M --tas MPS] [--out DIR]   A, B (JSON) and modes
    tune margins AIRFRAME [--alt M --tas MPS] [--out DIR]     loop margins (JSON)
    tune roll-gain [--crossover RAD_S | --phase-margin DEG]  quadrotor roll-attitude gain

Exit codes: 0 ok, 1 something did not trim / verify, 2 bad input (one-line error on stderr).
Default output folder: ``logs/tuning/<airframe>``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from rich.console import Console
from rich.table import Table

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2
AIRFRAMES = ("haps", "quadrotor")
out = Console()
err = Console(stderr=True, soft_wrap=True)


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2
        err.print(f"error: {message}", highlight=False, markup=False)
        raise SystemExit(EXIT_BAD_INPUT)


def _f(v, nd=4) -> str:
    if isinstance(v, float):
        return "" if math.isnan(v) else (f"{v:.2e}" if v != 0 and abs(v) < 1e-3 else f"{v:.{nd}g}")
    return str(v)


def _out_dir(args) -> Path:
    d = Path(args.out) if args.out else Path("logs") / "tuning" / args.airframe
    d.mkdir(parents=True, exist_ok=True)
    return d


def _altitudes(spec: str) -> tuple[float, ...]:
    """``START:STOP:STEP`` [m] (STOP included) -> altitudes."""
    try:
        start, stop, step = (float(x) for x in spec.split(":"))
    except ValueError:
        raise ValueError(f"--altitudes wants START:STOP:STEP in metres, got {spec!r}") from None
    if step <= 0 or stop < start:
        raise ValueError(f"--altitudes {spec!r}: needs STEP > 0 and STOP >= START")
    n = math.floor((stop - start) / step + 1e-9) + 1
    return tuple(start + k * step for k in range(n))


def cmd_trim(args) -> int:
    from sim.tuning import report, trim_haps, trim_quad

    if args.airframe == "haps" and args.eas is not None:
        rows = trim_haps.altitude_profile(_altitudes(args.altitudes), args.eas, check_in_jsbsim=not args.no_check)
        title = f"HAPS trim at EAS {args.eas:g} m/s by altitude (JSBSim trim and casadi trim)"
        stem = f"trim_haps_eas{args.eas:g}"
    elif args.airframe == "haps":
        rows = trim_haps.envelope(check_in_jsbsim=not args.no_check)
        title = "HAPS trim envelope (JSBSim trim and casadi trim)"
        stem = "trim_haps"
    else:
        rows = trim_quad.envelope()
        title = "Quadrotor trim (hover and level forward flight, root-finding on JSBSim)"
        stem = "trim_quadrotor"
    paths = report.write_all(rows, _out_dir(args), stem, title)
    t = Table(title=title)
    cols = ("method", "alt m", "TAS m/s", "ok", "alpha deg", "pitch deg", "elev", "throttle", "power W", "V/Vs")
    for c in (*cols, "res acc", "res rot"):
        t.add_column(c)
    for r in rows:
        t.add_row(
            r.method,
            _f(r.alt_m),
            _f(r.tas_mps),
            "yes" if r.ok else "[red]NO[/]",
            _f(r.alpha_deg),
            _f(r.pitch_deg),
            _f(r.elevator_norm),
            _f(r.throttle),
            _f(r.shaft_power_w),
            _f(r.stall_margin),
            _f(r.residual_acc),
            _f(r.residual_rot),
        )
    out.print(t)
    bad = [r for r in rows if not r.ok]
    for r in bad:
        out.print(f"[yellow]failed[/] {r.method} {r.alt_m:.0f} m {r.tas_mps:.1f} m/s: {r.reason}", highlight=False)
    out.print(f"{len(rows) - len(bad)}/{len(rows)} points trimmed; " + ", ".join(str(p) for p in paths.values()))
    return EXIT_OK


def _haps_linear(args):
    from sim.tuning.evaluator import JSBSimEvaluator
    from sim.tuning.linearize import linearize
    from sim.tuning.trim_haps import jsbsim_trim

    pt, plant = jsbsim_trim(args.alt, args.tas)
    if plant is None:
        raise ValueError(f"HAPS does not trim at {args.alt:.0f} m, {args.tas:.1f} m/s: {pt.reason}")
    return pt, plant, linearize(JSBSimEvaluator(plant))


def cmd_linearize(args) -> int:
    if args.airframe != "haps":
        raise ValueError(
            "linearize: only the haps has aerodynamic modes (the quadrotor's loops: `tune margins quadrotor`)"
        )
    from sim.tuning.modes import all_modes

    pt, _, lm = _haps_linear(args)
    modes = all_modes(lm)
    t = Table(title=f"HAPS modes at {args.alt:.0f} m, TAS {args.tas:.1f} m/s (alpha {pt.alpha_deg:.2f} deg)")
    for c in ("mode", "eigenvalue", "wn rad/s", "zeta", "period s", "tau s", "t2 s"):
        t.add_column(c)
    for m in modes:
        ev = m.eigenvalue
        t.add_row(
            m.name,
            f"{ev.real:.4f}{'+' if ev.imag >= 0 else '-'}{abs(ev.imag):.4f}j",
            _f(m.wn_rad_s),
            _f(m.zeta),
            _f(m.period_s),
            _f(m.time_const_s),
            _f(m.time_to_double_s),
        )
    out.print(t)
    path = _out_dir(args) / f"linear_haps_{args.alt:.0f}m_{args.tas:.1f}mps.json"
    path.write_text(
        json.dumps(
            {
                "trim": pt.row(),
                "states": list(lm.states),
                "state_units": list(lm.state_units),
                "inputs": list(lm.inputs),
                "A": lm.A.tolist(),
                "B": lm.B.tolist(),
                "x0": lm.x0.tolist(),
                "u0": lm.u0.tolist(),
                "modes": [m.row() | {"eig_re": m.eigenvalue.real} for m in modes],
            },
            indent=1,
            default=float,
        )
    )
    out.print(f"wrote {path}")
    return EXIT_OK


def _loop_rows(args):
    from sim.tuning.loops import analyse

    if args.airframe == "haps":
        from aircraft.haps.gains import HapsGains
        from sim.tuning.loops import HapsPitchGains, haps_pitch_loops

        _, plant, lm = _haps_linear(args)
        g = HapsGains.load()
        props = g.fcs_properties()
        sched = min(max(props["ap/qbar-ref-psf"] / plant["aero/qbar-psf"], g.sched_min), g.sched_max)
        l_el, l_th, T = haps_pitch_loops(lm, HapsPitchGains(g.kp_pitch, g.ki_pitch, g.kd_pitch, sched))
        return [analyse("pitch, opened at the elevator", l_el, T), analyse("pitch, opened at theta error", l_th, T)]
    from aircraft.quadrotor.gains import MultirotorGains
    from sim.tuning.loops import RatePid, identify_rotor_axis, quad_axis_loops

    mg = MultirotorGains.load()
    rows = []
    # yaw is left out: the motors' reaction torque leads (it follows the current, then decays as
    # the rpm changes), which the first-order plant fit of identify_rotor_axis does not describe
    for axis in ("roll", "pitch"):
        ax = identify_rotor_axis(axis)
        r = getattr(mg.rate, axis)
        kp_att = getattr(mg.attitude, f"kp_{axis}")
        l_rate, t_rate, l_att, t_att = quad_axis_loops(
            ax, RatePid(r.kp, r.ki, r.kd, 2 * math.pi * mg.rate.d_cutoff_hz), kp_att
        )
        rows += [
            analyse(f"{axis} rate (K {ax.K:.0f} rad/s2, tau {1000 * ax.tau_s:.0f} ms)", l_rate, t_rate),
            analyse(f"{axis} attitude", l_att, t_att),
        ]
    return rows


def cmd_margins(args) -> int:
    rows = _loop_rows(args)
    t = Table(title=f"{args.airframe} loop margins (python-control)")
    for c in (
        "loop",
        "crossover rad/s",
        "PM deg",
        "GM dB",
        "phase xover rad/s",
        "BW rad/s",
        "overshoot %",
        "rise s",
        "settle s",
    ):
        t.add_column(c)
    for r in rows:
        t.add_row(
            r.name,
            _f(r.crossover_rad_s),
            _f(r.phase_margin_deg, 3),
            _f(r.gain_margin_db, 3),
            _f(r.phase_crossover_rad_s),
            _f(r.bandwidth_rad_s),
            _f(r.overshoot_pct, 3),
            _f(r.rise_time_s, 3),
            _f(r.settling_time_s, 3),
        )
    out.print(t)
    path = _out_dir(args) / f"margins_{args.airframe}.json"
    path.write_text(json.dumps([r.row() for r in rows], indent=1, default=float))
    out.print(f"wrote {path}")
    return EXIT_OK


def cmd_roll_gain(args) -> int:
    from sim.tuning.tuner import tune_roll_attitude

    if (args.crossover is None) == (args.phase_margin is None):
        raise ValueError("roll-gain: give exactly one of --crossover, --phase-margin")
    if args.phase_margin is not None and not 0 < args.phase_margin < 90:
        raise ValueError("roll-gain: --phase-margin must be in (0, 90) deg")
    if args.crossover is not None and not 0 < args.crossover < 100:
        raise ValueError("roll-gain: --crossover must be in (0, 100) rad/s")
    p = tune_roll_attitude(args.crossover, args.phase_margin)
    r = p.linear
    out.print(
        f"proposed ap/kp-roll = {p.kp_roll:.3f} 1/s: crossover {r.crossover_rad_s:.2f} rad/s, PM "
        f"{r.phase_margin_deg:.1f} deg, GM {r.gain_margin_db:.1f} dB; overshoot linear "
        f"{r.overshoot_pct:.1f} %, JSBSim {p.jsbsim_overshoot_pct:.1f} %, 2nd-order estimate "
        f"{p.second_order_overshoot_pct:.1f} %",
        highlight=False,
    )
    return EXIT_OK


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="cosim tune", description="Trim, linearise and analyse the controller loops")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for name, fn, helptext in (
        ("trim", cmd_trim, "trim over the flight envelope"),
        ("linearize", cmd_linearize, "linear model and modes at a trim point"),
        ("margins", cmd_margins, "loop margins of the controllers as implemented"),
    ):
        s = sub.add_parser(name, help=helptext)
        s.add_argument("airframe", help=" | ".join(AIRFRAMES))
        s.add_argument("--out", help="output folder (default logs/tuning/<airframe>)")
        if name == "trim":
            s.add_argument("--no-check", action="store_true", help="HAPS: skip JSBSim's check of the casadi trims")
            s.add_argument("--eas", type=float, help="HAPS: trim at this equivalent airspeed [m/s] by altitude")
            s.add_argument("--altitudes", default="0:23000:1000", help="HAPS --eas: START:STOP:STEP [m]")
        else:
            s.add_argument("--alt", type=float, default=20_000.0, help="HAPS trim altitude MSL [m]")
            s.add_argument("--tas", type=float, default=29.7, help="HAPS true airspeed [m/s]")
        s.set_defaults(fn=fn)
    r = sub.add_parser("roll-gain", help="quadrotor roll-attitude gain for a crossover or phase margin")
    r.add_argument("--crossover", type=float, help="requested crossover [rad/s]")
    r.add_argument("--phase-margin", type=float, help="requested phase margin [deg]")
    r.set_defaults(fn=cmd_roll_gain, airframe="quadrotor", out=None)
    return p


def tune_main(argv: list[str] | None = None) -> int:
    """Entry point of ``cosim tune``; returns the exit code."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    try:
        if args.airframe not in AIRFRAMES:
            raise ValueError(f"unknown airframe {args.airframe!r} (known: {', '.join(AIRFRAMES)})")
        if getattr(args, "alt", None) is not None and not 0 <= args.alt <= 30_000:
            raise ValueError(f"--alt {args.alt} outside 0..30000 m")
        if getattr(args, "tas", None) is not None and not 0 < args.tas <= 100:
            raise ValueError(f"--tas {args.tas} outside (0, 100] m/s")
        return args.fn(args)
    except ValueError as exc:
        err.print(f"error: {exc}", highlight=False, markup=False)
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(tune_main())
