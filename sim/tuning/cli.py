"""``cosim tune ...``: trim, linearise, loop margins and gain tuning from the command line.

    tune trim AIRFRAME [--out DIR] [--no-check]       envelope trim: CSV, Markdown, PNG
    tune trim haps --eas 8 [--altitudes 0:23000:1000]  trims at one EAS from the ground up
    tune linearize AIRFRAME [--alt M --tas MPS] [--out DIR]   A, B (JSON) and modes
    tune margins AIRFRAME [--alt M --tas MPS] [--no-steps] [--out DIR]   every loop's margins,
        linear and JSBSim step figures (JSON); a warning for each phase margin under 30 deg
    tune gain AIRFRAME LOOP (--crossover RAD_S | --phase-margin DEG) [--no-verify] [--out DIR]
        the loop's gains scaled for the request, flown in JSBSim; proposal file (JSON) with its
        warnings (phase margin under 30 deg); an unreachable request is a one-line error
    tune roll-gain [AIRFRAME] (--crossover | --phase-margin)  = gain haps roll / quadrotor attitude

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


def _margin_rows(args) -> list[dict]:
    """Per loop: its margins and closed-loop figures, and (unless ``--no-steps``) its JSBSim step."""
    from sim.tuning.catalog import default_gains, loops_of
    from sim.tuning.loops import second_order_overshoot
    from sim.tuning.tuner import LOW_MARGIN_DEG

    gains = default_gains(args.airframe)
    rows = []
    for loop in loops_of(args.airframe, args.alt, args.tas):
        r = loop.analyse(gains)
        row = r.row() | {
            "name": loop.name,
            "opened_at": loop.opened_at,
            "second_order_overshoot_pct": second_order_overshoot(r.phase_margin_deg),
        }
        if not args.no_steps:
            st = loop.step(gains)
            row |= {"jsbsim_overshoot_pct": st.overshoot_pct, "jsbsim_settling_time_s": st.settling_time_s()}
        row["warning"] = (
            f"phase margin {r.phase_margin_deg:.1f} deg < {LOW_MARGIN_DEG:.0f} deg"
            if r.phase_margin_deg < LOW_MARGIN_DEG
            else ""
        )
        rows.append(row)
    return rows


def cmd_margins(args) -> int:
    rows = _margin_rows(args)
    t = Table(title=f"{args.airframe} loops: wc, BW rad/s; PM deg; overshoot OS %; settling Ts s")
    cols = {  # overshoot OS [%]: linear, second order from the PM, JSBSim; 2 % settling Ts [s]
        "loop": "name",
        "wc": "crossover_rad_s",
        "PM": "phase_margin_deg",
        "GM dB": "gain_margin_db",
        "BW": "bandwidth_rad_s",
        "OS lin": "overshoot_pct",
        "OS 2nd": "second_order_overshoot_pct",
        "OS JSB": "jsbsim_overshoot_pct",
        "Ts lin": "settling_time_s",
        "Ts JSB": "jsbsim_settling_time_s",
    }
    for c in cols:
        t.add_column(c, no_wrap=c == "loop")
    for r in rows:
        t.add_row(*(_f(r.get(k, math.nan), 3) for k in cols.values()))
    out.print(t)
    for r in rows:
        if r["warning"]:
            out.print(f"[yellow]warning[/] {args.airframe} {r['name']}: {r['warning']}", highlight=False)
    path = _out_dir(args) / f"margins_{args.airframe}.json"
    path.write_text(json.dumps(rows, indent=1, default=float))
    out.print(f"wrote {path}")
    return EXIT_OK


def cmd_gain(args) -> int:
    from sim.tuning.catalog import AIRFRAME_LOOPS, default_gains, loops_of
    from sim.tuning.tuner import propose, verify_in_jsbsim

    if (args.crossover is None) == (args.phase_margin is None):
        raise ValueError(f"{args.command}: give exactly one of --crossover, --phase-margin")
    if args.phase_margin is not None and not 0 < args.phase_margin < 180:
        raise ValueError(f"{args.command}: --phase-margin must be in (0, 180) deg")
    if args.crossover is not None and not args.crossover > 0:
        raise ValueError(f"{args.command}: --crossover must be > 0 rad/s")
    name = args.loop or {"haps": "roll", "quadrotor": "attitude"}[args.airframe]
    if name not in AIRFRAME_LOOPS[args.airframe]:
        raise ValueError(f"unknown {args.airframe} loop {name!r} (known: {', '.join(AIRFRAME_LOOPS[args.airframe])})")
    loop = next(lp for lp in loops_of(args.airframe, args.alt, args.tas) if lp.name == name)
    p = propose(loop, default_gains(args.airframe), args.crossover, args.phase_margin)
    if not args.no_verify:
        verify_in_jsbsim(loop, p)
    r = p.linear
    gains = ", ".join(f"{k} = {v:.4g}" for k, v in p.gains.items())
    jsb = "" if p.jsbsim_overshoot_pct is None else f", JSBSim {p.jsbsim_overshoot_pct:.1f} %"
    out.print(
        f"{args.airframe} {name}: {gains} (x{p.factor:.3g}): crossover {r.crossover_rad_s:.3g} rad/s, PM "
        f"{r.phase_margin_deg:.1f} deg, GM {r.gain_margin_db:.1f} dB; overshoot linear {r.overshoot_pct:.1f} %"
        f"{jsb}, 2nd-order estimate {p.second_order_overshoot_pct:.1f} %",
        highlight=False,
    )
    for w in p.warnings:
        out.print(f"[yellow]warning[/] {args.airframe} {name}: {w}", highlight=False)
    path = _out_dir(args) / f"proposal_{args.airframe}_{name}.json"
    path.write_text(json.dumps(p.row(), indent=1, default=float))
    out.print(f"wrote {path}")
    return EXIT_OK


def _point_args(s: argparse.ArgumentParser) -> None:
    s.add_argument("--alt", type=float, default=20_000.0, help="HAPS trim altitude MSL [m]")
    s.add_argument("--tas", type=float, default=29.7, help="HAPS true airspeed [m/s]")


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
            _point_args(s)
        if name == "margins":
            s.add_argument("--no-steps", action="store_true", help="skip the JSBSim step of each loop")
        s.set_defaults(fn=fn)
    for name, helptext in (
        ("gain", "gains of one loop for a crossover or phase margin, verified in JSBSim"),
        ("roll-gain", "roll loop gains (haps roll hold, quadrotor roll attitude): same as gain AIRFRAME roll|attitude"),
    ):
        r = sub.add_parser(name, help=helptext)
        if name == "gain":
            r.add_argument("airframe", help=" | ".join(AIRFRAMES))
            r.add_argument("loop", help="haps: roll | pitch; quadrotor: rate | attitude | velocity | position")
        else:
            r.add_argument("airframe", nargs="?", default="quadrotor", help=" | ".join(AIRFRAMES))
            r.set_defaults(loop=None)
        r.add_argument("--crossover", type=float, help="requested crossover [rad/s]")
        r.add_argument("--phase-margin", type=float, help="requested phase margin [deg]")
        r.add_argument("--no-verify", action="store_true", help="skip the JSBSim step with the proposed gains")
        r.add_argument("--out", help="output folder of the proposal file (default logs/tuning/<airframe>)")
        _point_args(r)
        r.set_defaults(fn=cmd_gain)
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
