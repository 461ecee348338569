"""``cosim``: run scenarios, inspect logs.

Exit codes: 0 success, 1 the run failed (its log is still written), 2 bad input (scenario,
batch or log file: one line naming the file and the field), 130 interrupted.
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import sys
from pathlib import Path

from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from sim import __version__

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INTERRUPTED = 0, 1, 2, 130
err = Console(stderr=True, soft_wrap=True)
out = Console()


def _error(exc: Exception) -> None:
    """One line on stderr (line breaks in the message shown as ``\\n``)."""
    text = str(exc).replace("\n", "\\n")
    err.print(f"[red]error:[/] {escape(text)}", highlight=False)


def _progress(counter: str, quiet: bool) -> Progress:
    """A transient progress bar on stderr: description, bar, ``counter`` (a rich column
    template), elapsed wall time."""
    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        TextColumn(counter),
        TimeElapsedColumn(),
        console=err,
        disable=quiet,
        transient=True,
    )


def _fmt_duration(s: float) -> str:
    h, rem = divmod(s, 3600)
    m, sec = divmod(rem, 60)
    return f"{int(h)}:{int(m):02d}:{sec:05.2f}"


def cmd_run(args) -> int:
    from sim.output_paths import path_under
    from sim.scenario import load_scenario

    scenario, text = load_scenario(args.scenario)
    scenario = _with_signing_key(scenario, args.mavlink_key)
    from sim.runner import RunFailed, run_scenario

    path = Path(args.output) if args.output else path_under(Path("logs"), f"{scenario.name}.mcap")
    duration = args.duration if args.duration is not None else scenario.duration
    signal.signal(signal.SIGTERM, signal.default_int_handler)
    progress = _progress("{task.fields[sim]} / {task.fields[end]} sim", args.quiet)
    with progress:
        task = progress.add_task(scenario.name, total=duration, sim=_fmt_duration(0), end=_fmt_duration(duration))

        def on_progress(t: float, end: float) -> None:
            progress.update(task, completed=t, sim=_fmt_duration(t))

        try:
            result = run_scenario(scenario, path, scenario_text=text, duration=duration, progress=on_progress)
        except RunFailed as exc:
            result = exc.result
            if args.debug:
                err.print_exception()
    _print_summary(result)
    return {"completed": EXIT_OK, "duration_elapsed": EXIT_OK, "interrupted": EXIT_INTERRUPTED}.get(
        result.status, EXIT_FAILED
    )


def _with_signing_key(scenario, key_file: str | None):
    """The scenario with ``--mavlink-key`` as its MAVLink signing key file; the key file (from
    either) is read now, so that a bad one is a one-line error before the run."""
    from sim.scenario import ScenarioError

    mav = scenario.mavlink
    if key_file is not None and not mav.enabled:
        raise ScenarioError("--mavlink-key: the scenario does not enable MAVLink ([mavlink] enabled = true)")
    if key_file is not None:
        mav = mav.model_copy(update={"signing_key_file": Path(key_file)})
        scenario = scenario.model_copy(update={"mavlink": mav})
    if mav.enabled and mav.signing_key_file is not None:
        from sim.mavlink.signing import SigningKeyError, load_key

        try:
            load_key(mav.signing_key_file)
        except SigningKeyError as exc:
            raise ScenarioError(str(exc)) from None
    return scenario


def _print_summary(r) -> None:
    colour = {"completed": "green", "duration_elapsed": "yellow"}.get(r.status, "red")
    t = Table(title=f"cosim run: {r.scenario}", show_header=False, title_justify="left")
    t.add_row("status", f"[{colour}]{r.status}[/]")
    if r.error:
        t.add_row("error", escape(r.error))
    t.add_row("sim time", _fmt_duration(r.sim_time_s))
    t.add_row("wall time", f"{r.wall_time_s:.1f} s")
    t.add_row("real-time factor", f"{r.real_time_factor:.0f}x")
    for name, m in r.missions.items():
        when = f" at {_fmt_duration(m.complete_time_s)}" if m.complete_time_s is not None else ""
        state = "[green]complete[/]" if m.complete else "[yellow]incomplete[/]"
        t.add_row(f"mission {name}", f"{state}: {m.reached}/{m.waypoints} waypoints{when}")
    out.print(t)
    out.print(f"log: {r.log_path}", soft_wrap=True, highlight=False)


def cmd_info(args) -> int:
    from sim.mcap_read import read_info

    info = read_info(args.log)
    run = info.metadata.get("run", {})
    res = info.metadata.get("result", {})
    out.print(f"{info.path}", soft_wrap=True, highlight=False)
    head = Table(show_header=False)
    head.add_row("scenario", run.get("scenario", "?"))
    head.add_row("seed", run.get("seed", "?"))
    head.add_row("result", res.get("status", "? (no result metadata)"))
    head.add_row("sim time", f"{info.start_s:.2f} .. {info.end_s:.2f} s")
    head.add_row("messages", str(info.messages))
    if not info.finished:
        head.add_row("file", "[yellow]unfinished (its writer never closed it): read up to its last complete chunk[/]")
    head.add_row("versions", f"cosim {run.get('cosim_version', '?')}, jsbsim {run.get('jsbsim_version', '?')}")
    head.add_row("attachments", ", ".join(info.attachments) or "-")
    out.print(head)
    topics = Table("topic", "schema", "encoding", "messages")
    for ti in info.topics:
        topics.add_row(ti.topic, ti.schema, ti.encoding, str(ti.count))
    out.print(topics)
    return EXIT_OK


def cmd_replay(args) -> int:
    from sim.mcap_read import read_info
    from sim.replay.report import write_report

    log = Path(args.log)
    out_dir = Path(args.output) if args.output else log.with_name(f"{log.stem}_report")
    report, metrics = write_report(log, out_dir)
    if not read_info(log).finished:
        err.print("[yellow]warning:[/] unfinished log, read up to its last complete chunk", highlight=False)
    if args.rerun_planner:
        from sim.replay.rerun import rerun_planner

        rep = rerun_planner(log, args.rerun_planner)
        out.print(
            f"planner re-run ({rep.vehicle}, {rep.planner}): {rep.same}/{rep.plans} plans identical "
            f"({rep.mode_plans} of ground-station mode planners); "
            f"max vertex difference {rep.max_position_diff_m:.3g} m / {rep.max_time_diff_s:.3g} s",
            soft_wrap=True,
            highlight=False,
        )
        for line in rep.differences:
            out.print(f"  {line}", soft_wrap=True, highlight=False)
    if args.json:
        import json

        out.print_json(json.dumps(metrics))
    else:
        out.print(f"report: {report}", soft_wrap=True, highlight=False)
        out.print(f"metrics: {out_dir / 'metrics.json'}", soft_wrap=True, highlight=False)
    return EXIT_OK


def cmd_export(args) -> int:
    from sim.replay.export import export_log

    log = Path(args.log)
    out_dir = Path(args.output) if args.output else log.with_name(f"{log.stem}_export")
    progress = _progress("{task.completed}/{task.total} messages", args.quiet)
    with progress:
        task = progress.add_task(f"export {log.name}", total=None)
        files = export_log(
            log, out_dir, args.format, args.topics, lambda k, total: progress.update(task, completed=k, total=total)
        )
    out.print(f"{len(files)} files in {out_dir}", soft_wrap=True, highlight=False)
    return EXIT_OK


def cmd_compare(args) -> int:
    from sim.replay.compare import compare_logs, write_csv, write_json

    rows = [r for r in compare_logs(args.a, args.b) if not (args.changed and r[1] == r[2])]
    to_stdout = False
    for target, write in ((args.json, write_json), (args.csv, write_csv)):
        if target == "-":
            write(rows, sys.stdout)
            to_stdout = True
        elif target is not None:
            with open(target, "w", encoding="utf-8", newline="") as fh:
                write(rows, fh)
    if to_stdout:
        return EXIT_OK
    t = Table("metric", "A", "B", "B - A", title=f"A = {args.a}   B = {args.b}", title_justify="left")
    for k, x, y, d in rows:
        t.add_row(k, _cell(x), _cell(y), "" if d is None else f"{d:+.4g}")
    # off a terminal (a pipe, a file) the table takes its natural width: full metric names
    (out if out.is_terminal else Console(width=1_000_000)).print(t)
    return EXIT_OK


def _cell(v) -> str:
    return f"{v:.4g}" if isinstance(v, float) else ("–" if v is None else str(v))


def cmd_batch(args) -> int:
    from sim.batch import load_batch, run_batch

    name, runs = load_batch(args.batch, args.output)
    out_dir = Path(args.output) if args.output else Path("logs") / "batch" / name  # name checked by load_batch
    executor = None
    client = None
    if args.dask:
        from distributed import Client

        client = Client(args.dask)
        executor = client.get_executor()
    failures = 0
    signal.signal(signal.SIGTERM, signal.default_int_handler)
    progress = Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total} runs"),
        TextColumn("{task.fields[failed]} failed"),
        TimeElapsedColumn(),
        console=err,
        disable=args.quiet,
        transient=True,
    )
    try:
        with progress:
            task = progress.add_task(name, total=len(runs), failed=0)

            def on_run(k: int, total: int, row: dict) -> None:
                nonlocal failures
                failures += row.get("status") == "failed"
                progress.update(task, total=total, completed=k, failed=failures)

            rows = run_batch(
                runs, out_dir, executor=executor, workers=args.workers, progress=on_run, resume=not args.no_resume
            )
    finally:
        if client is not None:
            client.close()
    failed = sum(r.get("status") == "failed" for r in rows)
    cut = sum(r.get("status") == "interrupted" for r in rows)
    crashed = sum(r.get("status") == "crashed" for r in rows)
    out.print(
        f"{len(rows)} runs, {failed} failed, {crashed} crashed, {cut} interrupted (flown again on resume); "
        f"results: {out_dir / 'results.csv'}",
        soft_wrap=True,
        highlight=False,
    )
    return EXIT_INTERRUPTED if cut else EXIT_OK if failed == 0 else EXIT_FAILED


def _draw_indices(text: str) -> list[int]:
    """``--draws``: comma-separated draw indices."""
    try:
        return [int(x) for x in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"comma-separated draw indices, got {text!r}") from None


def cmd_encounters(args) -> int:
    from sim.encounters.campaign import load_campaign, run_campaign

    out_dir = Path(args.output) if args.output else Path("logs") / "encounters" / Path(args.campaign).stem
    campaign = load_campaign(args.campaign, out_dir, args.limit, args.draws)
    executor = None
    client = None
    if args.dask:
        from distributed import Client

        client = Client(args.dask)
        executor = client.get_executor()
    progress = _progress("{task.completed}/{task.total} runs", args.quiet)
    try:
        with progress:
            task = progress.add_task(campaign.name, total=len(campaign.runs))
            summary = run_campaign(
                campaign,
                out_dir,
                executor=executor,
                workers=args.workers,
                progress=lambda k, total, _row: progress.update(task, total=total, completed=k),
                resume=not args.no_resume,
            )
    finally:
        if client is not None:
            client.close()
    for key, s in summary.items():
        out.print(
            f"{key}: {s['n']} encounters: NMAC {s.get('nmac_mitigated')} mitigated / {s.get('nmac_unmitigated')} "
            f"unmitigated, risk ratio {s.get('risk_ratio')}, induced {s.get('induced_nmac')}, "
            f"completion {s.get('completion_rate')}",
            soft_wrap=True,
            highlight=False,
        )
    out.print(f"report: {out_dir / 'report.md'}", soft_wrap=True, highlight=False)
    return EXIT_OK if all(s.get("failed_runs", 0) == 0 for s in summary.values()) else EXIT_FAILED


def cmd_validate(args) -> int:
    from sim.scenario import load_scenario

    scenario, _ = load_scenario(args.scenario)
    out.print(f"{args.scenario}: ok ({scenario.name}, {len(scenario.vehicle)} vehicle(s))")
    return EXIT_OK


def _sim_seconds(text: str) -> float:
    """A sim time [s]: a finite number > 0."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number of seconds: {text!r}") from None
    if not math.isfinite(v) or v <= 0.0:
        raise argparse.ArgumentTypeError(f"must be a finite number of seconds > 0, got {text!r}")
    return v


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="cosim", description="Closed-loop JSBSim co-simulation harness")
    p.add_argument("--version", action="version", version=f"cosim {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="fly a scenario and log it to MCAP")
    r.add_argument("scenario", help="scenario TOML file")
    r.add_argument("-o", "--output", help="MCAP log path (default logs/<scenario name>.mcap)")
    r.add_argument("--duration", type=_sim_seconds, help="sim time to fly [s] (default: the scenario's)")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    r.add_argument("--debug", action="store_true", help="print the traceback of a failed run")
    r.add_argument(
        "--mavlink-key",
        metavar="FILE",
        help="MAVLink 2 signing: a file holding the passphrase (overrides the scenario's signing_key_file)",
    )
    r.set_defaults(fn=cmd_run)
    i = sub.add_parser("info", help="summarise an MCAP log")
    i.add_argument("log")
    i.set_defaults(fn=cmd_info)
    rp = sub.add_parser("replay", help="metrics, plots and a Markdown report from a run log")
    rp.add_argument("log")
    rp.add_argument("-o", "--output", help="report folder (default: <log>_report next to the log)")
    rp.add_argument("--json", action="store_true", help="also print the metrics as JSON")
    rp.add_argument(
        "--rerun-planner",
        metavar="VEHICLE",
        help="re-run VEHICLE's planner open-loop on the logged estimates and threats and "
        "compare its plans with the recorded ones",
    )
    rp.set_defaults(fn=cmd_replay)
    cp = sub.add_parser("compare", help="A/B: metrics of two run logs side by side")
    cp.add_argument("a")
    cp.add_argument("b")
    cp.add_argument("--changed", action="store_true", help="only the metrics that differ")
    cp.add_argument("--json", metavar="FILE", help="write the rows as JSON to FILE ('-': standard output, no table)")
    cp.add_argument("--csv", metavar="FILE", help="write the rows as CSV to FILE ('-': standard output, no table)")
    cp.set_defaults(fn=cmd_compare)
    x = sub.add_parser("export", help="a run log's topics to Parquet or CSV, one file per topic")
    x.add_argument("log")
    x.add_argument("--format", required=True, choices=["parquet", "csv"], help="file format")
    x.add_argument("--topics", nargs="+", metavar="TOPIC", help="topics to export (default: all)")
    x.add_argument("-o", "--output", help="output folder (default: <log>_export next to the log)")
    x.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    x.set_defaults(fn=cmd_export)
    b = sub.add_parser("batch", help="sweep / Monte-Carlo runs from a batch file")
    b.add_argument("batch", help="batch TOML file")
    b.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="local worker processes")
    b.add_argument("--dask", metavar="ADDRESS", help="run on a Dask distributed scheduler instead")
    b.add_argument("-o", "--output", help="output folder (default logs/batch/<name>)")
    b.add_argument("--no-resume", action="store_true", help="re-run runs that already finished")
    b.add_argument("-q", "--quiet", action="store_true")
    b.set_defaults(fn=cmd_batch)
    e = sub.add_parser("encounters", help="encounter campaign: paired mitigated/unmitigated runs, risk ratio")
    e.add_argument("campaign", help="campaign TOML file")
    e.add_argument("-o", "--output", help="output folder (default logs/encounters/<campaign file name>)")
    e.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="local worker processes")
    e.add_argument("--dask", metavar="ADDRESS", help="run on a Dask distributed scheduler instead")
    e.add_argument("--no-resume", action="store_true", help="re-run runs that already finished")
    chosen = e.add_mutually_exclusive_group()
    chosen.add_argument("--limit", type=int, help="fly only the first N draws (the full campaign resumes them)")
    chosen.add_argument(
        "--draws",
        type=_draw_indices,
        metavar="I,J,...",
        help="fly only these draw indices (the same runs as in the full campaign)",
    )
    e.add_argument("-q", "--quiet", action="store_true")
    e.set_defaults(fn=cmd_encounters)
    sub.add_parser("tune", help="trim, linearise, loop margins, gain proposals (cosim tune --help)")
    v = sub.add_parser("validate", help="check a scenario file without flying it")
    v.add_argument("scenario")
    v.set_defaults(fn=cmd_validate)
    return p


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["tune"]:  # its own parser, options included
        from sim.tuning.cli import tune_main

        return tune_main(argv[1:])
    args = build_parser().parse_args(argv)
    from sim.batch import BatchError
    from sim.encounters.model import CampaignError
    from sim.mcap_log import LogWriteError
    from sim.mcap_read import LogReadError
    from sim.output_paths import OutputPathError
    from sim.scenario import ScenarioError

    try:
        return args.fn(args)
    except (
        ScenarioError,
        LogReadError,
        LogWriteError,
        BatchError,
        CampaignError,
        OutputPathError,
    ) as exc:  # bad input: one line, exit 2
        _error(exc)
        return EXIT_BAD_INPUT
    except OSError as exc:  # an output folder that cannot be written, a file that vanished: one line
        _error(OSError(f"{exc.filename or ''}: {exc.strerror or exc}".lstrip(": ")))
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        err.print("interrupted")
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
