"""Encounter campaigns on the batch machinery: a campaign file expands into paired runs
(mitigated and unmitigated, :data:`~sim.encounters.geometry.MODES`) of sampled encounters, flown by
:func:`sim.batch.run_batch` (process pool or Dask, resumable), then tabled and summarised.

A campaign file (TOML)::

    name = "geometric_quad_pairs"
    seed = 17                      # master seed: parameters and run seeds derive from it
    encounters = 500
    latin_hypercube = true         # optional (default false: independent draws)
    altitude = 420                 # ownship altitude at the CPA [m MSL]
    after_cpa = 10                 # flown past the CPA to the mission's end [s]
    slack = 30                     # extra sim time for detours [s]
    keep_mcaps = "failures"        # or "all": MCAPs of every run
    keep_below_m = 40              # optional: also keep encounters a mitigated run passes closer [m]
    min_relative_speed = 0.5       # [m/s] draws closing slower are skipped (counted in summary.json)
    start_margin = 2.5             # [m] draws starting inside the NMAC cylinder grown by it are skipped
    [metrics]                      # the scenarios' [metrics]: NMAC cylinder, well clear [m]
    nmac_horizontal = 5
    [ownship]
    aircraft = "quadrotor"
    planner = { type = "geometric", rate_hz = 10, options = { conflict_horizon_s = 2.0 } }
    [intruder]
    kind = "object"                # object | quadrotor | haps | cooperative
    radius = 0.5
    count = 1                      # 2: a cooperative triple (approach_angle_2, intruder_speed_2, hmd_2)
    [parameters]                   # sim.encounters.model.PARAMETERS: number or distribution
    approach_angle = { uniform = [0, 360] }
    [[variant]]                    # optional, repeatable: the mitigated run flown several ways
    name = "utm"                   # its mode in the outputs (run ids, encounters.csv, summary.json)
    utm = { frame = 1.0 }          # planner, utm, utm_link, peer_link: sim.encounters.geometry.Variant

Without ``[[variant]]`` every encounter is flown ``mitigated`` and ``unmitigated``; with them,
once per variant (mode = its name) and once unmitigated, all with the encounter's seed: the
variants are compared on the same draws against one shared unmitigated run.

Outputs in the campaign folder: ``runs/`` (the batch's per-run JSON; MCAPs of failed, NMAC and
induced-NMAC encounters, or all), ``encounters.csv``, ``summary.json`` (keyed by the planner, or
by variant), ``report.md``.
"""

from __future__ import annotations

import csv
import json
import math
import re
import tomllib
from collections.abc import Callable, Collection
from concurrent.futures import Executor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydantic import ValidationError

from sim.batch import RunSpec, run_batch
from sim.encounters.aggregate import Pair, by_bin, geometry_bins, summarise
from sim.encounters.geometry import (
    DEFAULT_ORIGIN,
    INTRUDER,
    INTRUDER2,
    INTRUDER_KINDS,
    OWN,
    EncounterSetup,
    Variant,
    build_scenario,
    intruder_count,
    legs,
    relative_speed,
    second_intruder,
    start_within,
)
from sim.encounters.model import PARAMETERS, CampaignError, parse_distributions, sample
from sim.scenario import Metrics, ScenarioError, parse_scenario

FT = 0.3048
# NMAC cylinders [m]: RTCA DO-365 (manned-scale traffic, here the HAPS) and the project's small-UAS
# body-scale volume (docs/encounters.md)
NMAC_DO365 = {"nmac_horizontal": 500 * FT, "nmac_vertical": 100 * FT}
NMAC_SMALL_UAS = {"nmac_horizontal": 5.0, "nmac_vertical": 2.5}
# [m] draws whose vehicles start within the NMAC cylinder grown by this are skipped: NMACs by
# construction. It exceeds the 2 m by which a flown horizontal geometry differs from the sampled
# one on the default EKF (docs/encounters.md), so no flown start is inside the cylinder.
START_MARGIN = 2.5
TOP_KEYS = {"name", "seed", "encounters", "latin_hypercube", "altitude", "after_cpa", "slack", "keep_mcaps"}
TOP_KEYS |= {"min_relative_speed", "start_margin", "keep_below_m"}
TOP_KEYS |= {"surveillance_rate_hz", "origin", "metrics", "ownship", "intruder", "parameters", "variant"}
VARIANT_KEYS = ("name", "planner", "utm", "utm_link", "peer_link")


@dataclass(frozen=True, slots=True)
class Encounter:
    index: int
    seed: int
    params: dict[str, float]


@dataclass(frozen=True, slots=True)
class Campaign:
    name: str
    setup: EncounterSetup
    encounters: list[Encounter]  # flown: draws closing at min_relative_speed or faster
    runs: list[RunSpec]  # per encounter: one per variant, then unmitigated
    keep_mcaps: str
    skipped: int = 0  # draws closing slower than min_relative_speed or starting too close
    variants: tuple[Variant, ...] = (Variant(),)
    named: bool = False  # variants from the file ([[variant]]), not the one default
    keep_below_m: float = 0.0  # a mitigated run passing closer (horizontal) [m] keeps its encounter's logs

    @property
    def planner(self) -> str:
        return self.setup.ownship["planner"].get("type", "follow_mission")

    @property
    def modes(self) -> tuple[str, ...]:
        """The modes each encounter is flown in, in run order: the variants', then unmitigated."""
        return (*(v.name for v in self.variants), "unmitigated")

    def summary_key(self, variant: Variant) -> str:
        """A variant's key in the summary: its name, or the planner's without ``[[variant]]``."""
        return variant.name if self.named else self.planner


def parse_variants(table: object, src: str) -> tuple[Variant, ...]:
    """The ``[[variant]]`` tables: unique names (letters, digits, ``_``, not ``unmitigated``) and
    only :data:`VARIANT_KEYS`, each other key a table."""
    if not isinstance(table, list) or not table or not all(isinstance(v, dict) for v in table):
        raise CampaignError(f"{src}: variant: an array of tables [[variant]]")
    out = []
    for k, v in enumerate(table):
        name = v.get("name")
        unknown = sorted(set(v) - set(VARIANT_KEYS))
        if unknown:
            raise CampaignError(f"{src}: variant[{k}].{unknown[0]}: unknown key (known: {', '.join(VARIANT_KEYS)})")
        if not isinstance(name, str) or not re.fullmatch(r"\w+", name) or name == "unmitigated":
            raise CampaignError(f"{src}: variant[{k}].name: letters, digits and _, not 'unmitigated', got {name!r}")
        bad = [key for key in VARIANT_KEYS[1:] if key in v and not isinstance(v[key], dict)]
        if bad:
            raise CampaignError(f"{src}: variant[{k}].{bad[0]}: a table")
        out.append(Variant(name, **{key: v[key] for key in VARIANT_KEYS[1:] if key in v}))
    names = [v.name for v in out]
    if len(set(names)) < len(names):
        raise CampaignError(f"{src}: variant: repeated name {next(n for n in names if names.count(n) > 1)!r}")
    return tuple(out)


def run_seed(master: int, index: int) -> int:
    """Seed of encounter ``index`` (both of its runs) from the master seed."""
    return int(np.random.SeedSequence([master, index]).generate_state(1, dtype=np.uint64)[0] >> 1)


def load_campaign(
    path: str | Path, out_dir: str | Path, limit: int | None = None, draws: Collection[int] | None = None
) -> Campaign:
    """Parse, sample and expand a campaign file into validated paired runs logged under ``out_dir``.
    ``limit``: only the first draws; ``draws``: only these draw indices. Either way the runs are
    the same as in the full campaign (ids, seeds, scenarios), which resumes them."""
    path = Path(path)
    src = str(path)
    try:
        cfg = tomllib.loads(path.read_text())
    except OSError as exc:
        raise CampaignError(f"{src}: cannot read campaign file ({exc.strerror})") from None
    except tomllib.TOMLDecodeError as exc:
        raise CampaignError(f"{src}: not valid TOML: {exc}") from None
    unknown = sorted(set(cfg) - TOP_KEYS)
    if unknown:
        raise CampaignError(f"{src}: {unknown[0]}: unknown key")
    for key in ("ownship", "intruder"):
        if not isinstance(cfg.get(key), dict):
            raise CampaignError(f"{src}: {key}: missing table [{key}]")
    own, intruder = cfg["ownship"], cfg["intruder"]
    if "aircraft" not in own or "planner" not in own:
        raise CampaignError(f"{src}: ownship: needs aircraft and planner")
    if intruder.get("kind") not in INTRUDER_KINDS:
        raise CampaignError(f"{src}: intruder.kind: one of {', '.join(INTRUDER_KINDS)}, got {intruder.get('kind')!r}")
    if intruder.get("count", 1) not in (1, 2) or (intruder.get("count", 1) == 2 and intruder["kind"] != "cooperative"):
        raise CampaignError(f"{src}: intruder.count: 1, or 2 for kind 'cooperative', got {intruder.get('count')!r}")
    keep = cfg.get("keep_mcaps", "failures")
    if keep not in ("failures", "all"):
        raise CampaignError(f"{src}: keep_mcaps: 'failures' or 'all', got {keep!r}")
    keep_below = cfg.get("keep_below_m", 0.0)
    if isinstance(keep_below, bool) or not isinstance(keep_below, int | float) or not 0 <= keep_below < math.inf:
        raise CampaignError(f"{src}: keep_below_m: a distance >= 0 [m], got {keep_below!r}")
    n = cfg.get("encounters", 0)
    if not isinstance(n, int) or n < 1:
        raise CampaignError(f"{src}: encounters: a positive integer, got {n!r}")
    default_nmac = NMAC_DO365 if intruder["kind"] == "haps" else NMAC_SMALL_UAS
    setup_kw = {k: float(cfg[k]) for k in ("altitude", "after_cpa", "slack", "surveillance_rate_hz") if k in cfg}
    setup = EncounterSetup(
        own,
        intruder,
        origin=cfg.get("origin", dict(DEFAULT_ORIGIN)),
        metrics=default_nmac | cfg.get("metrics", {}),
        **setup_kw,
    )
    name = cfg.get("name", path.stem)
    master = int(cfg.get("seed", 0))
    dists = parse_distributions(cfg.get("parameters", {}), f"{src}: parameters")
    sampled = sample(dists, n, master, bool(cfg.get("latin_hypercube", False)))
    picked = range(len(sampled))[:limit] if draws is None else sorted(set(draws))
    outside = [i for i in picked if not 0 <= i < len(sampled)]
    if outside:
        raise CampaignError(f"{src}: draw {outside[0]}: out of range 0..{len(sampled) - 1}")
    named = "variant" in cfg
    variants = parse_variants(cfg["variant"], src) if named else (Variant(),)
    min_rel = float(cfg.get("min_relative_speed", 0.5))
    margin = float(cfg.get("start_margin", START_MARGIN))
    if not (math.isfinite(margin) and margin >= 0):
        raise CampaignError(f"{src}: start_margin: a distance >= 0 [m], got {cfg['start_margin']!r}")
    try:
        nmac = Metrics.model_validate(setup.metrics)
    except ValidationError as exc:
        raise CampaignError(f"{src}: metrics: {exc.errors()[0]['msg']}") from None
    too_close = (nmac.nmac_horizontal + margin, nmac.nmac_vertical + margin)
    out = Path(out_dir)
    encounters, runs = [], []
    triple = intruder_count(setup) == 2
    for i in picked:
        params = sampled[i]
        if relative_speed(params) < min_rel or (triple and relative_speed(second_intruder(params)) < min_rel):
            continue
        if start_within(params, setup, *too_close):
            continue
        enc = Encounter(i, run_seed(master, i), params)
        encounters.append(enc)
        for variant, mode in [(v, "mitigated") for v in variants] + [(Variant(), "unmitigated")]:
            label = variant.name if mode == "mitigated" else mode
            run_id = f"{name}_{i:05d}_{label}"
            try:
                scen = build_scenario(params, setup, enc.seed, mode, run_id, variant)
                parse_scenario(scen, f"{src} encounter {i} ({label})")
            except (ScenarioError, CampaignError) as exc:
                raise CampaignError(f"{src}: {exc}") from None
            runs.append(
                RunSpec(
                    run_id,
                    scen,
                    None,
                    str(out / "runs" / f"{run_id}.mcap"),
                    str(out / "runs" / f"{run_id}.json"),
                    {"encounter": i, "mode": label, "seed": enc.seed, **params},
                )
            )
    if not encounters:
        raise CampaignError(
            f"{src}: no encounter closes at min_relative_speed ({min_rel:g} m/s) or faster and starts outside "
            f"the NMAC cylinder + start_margin ({margin:g} m)"
        )
    return Campaign(
        name, setup, encounters, runs, keep, len(picked) - len(encounters), variants, named, float(keep_below)
    )


def outcome(row: dict, kind: str, count: int = 1) -> dict:
    """One run's encounter metrics from its batch row; a triple's are the closest pair's (NMAC and
    loss of well clear: any pair's)."""
    m = {k.removeprefix("metric."): v for k, v in row.items() if k.startswith("metric.")}
    if kind == "object":
        seps = [f"vehicles.{OWN}.clearance.object.{INTRUDER}"]
    elif count == 2:
        seps = [f"separation.{a}-{b}" for a, b in ((OWN, INTRUDER), (OWN, INTRUDER2), (INTRUDER, INTRUDER2))]
    else:
        seps = [f"separation.{OWN}-{INTRUDER}"]
    sep = min(seps, key=lambda k: m.get(f"{k}.min_horizontal_m", math.inf))
    vehicles = [OWN] if kind != "cooperative" else [OWN, INTRUDER, INTRUDER2][: 1 + count]
    return {
        "status": row.get("status"),
        "min_horizontal_m": m.get(f"{sep}.min_horizontal_m"),
        "min_vertical_m": m.get(f"{sep}.min_vertical_m"),
        "vertical_at_min_horizontal_m": m.get(f"{sep}.vertical_at_min_horizontal_m"),
        "cpa_t": m.get(f"{sep}.t"),
        "nmac": any(bool(m.get(f"{k}.nmac")) for k in seps),
        "lowc": any(bool(m.get(f"{k}.lowc")) for k in seps),
        "complete": all(bool(m.get(f"vehicles.{v}.mission.complete")) for v in vehicles),
        "time_s": m.get(f"vehicles.{OWN}.mission.time_s"),
        "path_length_m": m.get(f"vehicles.{OWN}.mission.path_length_m"),
        "latency_p95_ms": m.get(f"vehicles.{OWN}.planner_latency.p95_ms"),
    }


def _extra(a: float | None, b: float) -> float | None:
    return a - b if a is not None else None


def tabulate(c: Campaign, rows: list[dict]) -> tuple[list[dict], dict[str, list[Pair]]]:
    """encounters.csv rows (one per encounter and mode, in run order: parameters, outcome, and the
    ownship's extra time and path over its planned straight leg, start to waypoint at cruise speed)
    and, per variant, the pairs of encounters whose variant run and unmitigated run did not fail.
    Against the plan, not the unmitigated run: that one stops where the two collide."""
    kind, m = c.setup.intruder["kind"], len(c.modes)
    table: list[dict] = []
    pairs: dict[str, list[Pair]] = {v.name: [] for v in c.variants}
    for k, enc in enumerate(c.encounters):
        plan_t = enc.params["time_to_cpa"] + c.setup.after_cpa
        plan_m = float(np.linalg.norm(legs(enc.params, c.setup)[0].velocity)) * plan_t
        *mits, unm = (outcome(r, kind, intruder_count(c.setup)) for r in rows[m * k : m * (k + 1)])
        for mode, o in zip(c.modes, (*mits, unm), strict=True):
            extra = {"extra_time_s": _extra(o["time_s"], plan_t), "extra_path_m": _extra(o["path_length_m"], plan_m)}
            table.append({"encounter": enc.index, "mode": mode, "seed": enc.seed, **enc.params, **o, **extra})
            if o is not unm and o["status"] != "failed" and unm["status"] != "failed":
                pairs[mode].append(
                    Pair(
                        o["nmac"],
                        unm["nmac"],
                        o["lowc"],
                        unm["lowc"],
                        o["complete"],
                        geometry_bins(enc.params),
                        extra["extra_path_m"],
                        o["min_horizontal_m"],
                    )
                )
    return table, pairs


def keep_logs(c: Campaign, table: list[dict]) -> set[str]:
    """Run ids whose MCAP is kept: every run of an encounter with a failed run, a mitigated NMAC
    (induced or not), an incomplete mitigated mission or a mitigated minimum horizontal separation
    below ``keep_below_m`` (a breached margin) in any variant (every run with
    ``keep_mcaps = "all"``)."""
    keep, m = set(), len(c.modes)
    for k in range(len(c.encounters)):
        rows = table[m * k : m * (k + 1)]
        bad = any(r["status"] == "failed" for r in rows)
        bad |= any(r["nmac"] or not r["complete"] for r in rows[:-1])
        bad |= any(r["min_horizontal_m"] is not None and r["min_horizontal_m"] < c.keep_below_m for r in rows[:-1])
        if bad or c.keep_mcaps == "all":
            keep |= {spec.run_id for spec in c.runs[m * k : m * (k + 1)]}
    return keep


def run_campaign(
    c: Campaign,
    out_dir: str | Path,
    executor: Executor | None = None,
    workers: int = 1,
    progress: Callable[[int, int, dict], None] | None = None,
    resume: bool = True,
) -> dict:
    """Fly every run (finished ones skipped when ``resume``), write the outputs, return the
    summary ({planner, or variant name: summary with ``bins``})."""
    from sim.encounters.report import write_report

    out = Path(out_dir)
    rows = run_batch(c.runs, out, executor=executor, workers=workers, progress=progress, resume=resume)
    table, pairs = tabulate(c, rows)
    kept = keep_logs(c, table)
    for spec, row in zip(c.runs, table, strict=True):
        log = Path(spec.log_path)
        if spec.run_id not in kept:
            log.unlink(missing_ok=True)
        row["mcap"] = str(log.relative_to(out)) if log.exists() else ""
    write_table(out / "encounters.csv", table)
    summary = {}
    for v in c.variants:
        failed = sum(r["status"] == "failed" for r in table if r["mode"] in (v.name, "unmitigated"))
        s = summarise(pairs[v.name]) | {"failed_runs": failed, "skipped_draws": c.skipped}
        summary[c.summary_key(v)] = s | {"bins": by_bin(pairs[v.name])}
    (out / "summary.json").write_text(json.dumps(summary, indent=2, sort_keys=True))
    write_report(out, c, table, summary)
    return summary


def write_table(path: Path, table: list[dict]) -> None:
    first = ["encounter", "mode", "seed", *PARAMETERS]
    columns = first + [k for k in table[0] if k not in first]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns)
        w.writeheader()
        w.writerows(table)
