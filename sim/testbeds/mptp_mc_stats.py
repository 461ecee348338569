"""Statistics and the Markdown table of the MPTP Monte-Carlo study (mptp_montecarlo.py).

Success rates get Wilson score 95 % intervals (scipy); mean runtimes a t interval; the runtime
of a heuristic relative to the baseline (EDH) is the ratio of the mean runtimes over the same
trials with a paired bootstrap 95 % interval (trials resampled, ``BOOTSTRAP`` draws, fixed
seed), because absolute wall-clock times on a loaded machine are not comparable between runs.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

BASELINE = "edh"
FAST_CAP = 20  # the thesis also reports success within 20 explored states
BOOTSTRAP = 2000
LEVEL = 0.95

# seed 002, 6.2 (first study: n = 10,000, cap 100, EDH and SSPH); runtimes are not reported there
THESIS = {
    "edh": {"success": 77.60, "fast": 70.99, "efficiency_both": 85.07},
    "ssph": {"success": 99.63, "fast": 94.79, "efficiency_both": 93.74},
}


def wilson(k: int, n: int, level: float = LEVEL) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion k/n."""
    if n == 0:
        return (math.nan, math.nan)
    ci = stats.binomtest(int(k), int(n)).proportion_ci(confidence_level=level, method="wilson")
    return (float(ci.low), float(ci.high))


def t_interval(x: np.ndarray, level: float = LEVEL) -> tuple[float, float]:
    """t interval of the mean of x."""
    x = np.asarray(x, float)
    if len(x) < 2:
        return (math.nan, math.nan)
    if np.ptp(x) == 0.0:
        return (float(x[0]), float(x[0]))
    lo, hi = stats.t.interval(level, len(x) - 1, loc=x.mean(), scale=stats.sem(x))
    return (float(lo), float(hi))


def ratio_of_means(a: np.ndarray, b: np.ndarray, level: float = LEVEL, seed: int = 0) -> tuple[float, float, float]:
    """mean(a) / mean(b) for paired samples and its bootstrap percentile interval."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, len(a), (BOOTSTRAP, len(a)))
    boot = a[idx].mean(axis=1) / b[idx].mean(axis=1)
    lo, hi = np.quantile(boot, [(1 - level) / 2, (1 + level) / 2])
    return float(a.mean() / b.mean()), float(lo), float(hi)


def _paired(rows: list[dict]) -> dict[str, dict[tuple[int, int], dict]]:
    out: dict[str, dict[tuple[int, int], dict]] = {}
    for r in rows:
        out.setdefault(r["heuristic"], {})[(r["field"], r["index"])] = r
    return out


def summarise(rows: list[dict]) -> dict:
    """Per heuristic: success (and within FAST_CAP expansions) with Wilson intervals, EXST and
    search efficiency TRST/EXST of its successes, runtime mean with t interval and its ratio
    to the baseline on the trials both ran; over the trials both succeed in: mean lengths."""
    by = _paired(rows)
    keys = sorted(set.intersection(*(set(d) for d in by.values())))
    out: dict = {"trials": len(keys), "fields": len({k[0] for k in keys}), "heuristics": {}}
    out["same_search"] = sum(
        len({(d[k]["status"], d[k]["exst"], round(float(np.nan_to_num(d[k]["length_m"])), 3)) for d in by.values()})
        == 1
        for k in keys
    )
    cov = {r["field"]: (r["coverage_issue"], r["coverage_horizon"]) for r in rows if "coverage_issue" in r}
    if cov:
        c = np.array(list(cov.values()))
        out["coverage"] = {"issue": float(c[:, 0].mean()), "horizon": float(c[:, 1].mean())}
    for h, d in by.items():
        rs = [d[k] for k in keys]
        ok = np.array([r["success"] for r in rs], bool)
        exst = np.array([r["exst"] for r in rs], float)
        trst = np.array([r["trst"] for r in rs], float)
        rt = np.array([r["runtime_s"] for r in rs], float)
        fast = ok & (exst <= FAST_CAP)
        entry = {
            "n": len(rs),
            "success": int(ok.sum()),
            "success_ci": wilson(int(ok.sum()), len(rs)),
            "errors": sum(str(r["status"]).startswith("error") for r in rs),
            "fast_success": int(fast.sum()),
            "fast_ci": wilson(int(fast.sum()), len(rs)),
            "exst_mean_ok": float(exst[ok].mean()) if ok.any() else math.nan,
            "efficiency_ok": float((trst[ok] / exst[ok]).mean()) if ok.any() else math.nan,
            "runtime_mean_s": float(rt.mean()),
            "runtime_ci_s": t_interval(rt),
        }
        if h != BASELINE and BASELINE in by:
            base = np.array([by[BASELINE][k]["runtime_s"] for k in keys], float)
            entry["runtime_ratio"] = ratio_of_means(rt, base)
        out["heuristics"][h] = entry
    if BASELINE in by and len(by) == 2:
        other = next(h for h in by if h != BASELINE)
        both = [k for k in keys if by[BASELINE][k]["success"] and by[other][k]["success"]]
        la = np.array([by[BASELINE][k]["length_m"] for k in both], float)
        lb = np.array([by[other][k]["length_m"] for k in both], float)
        eff = {h: float(np.mean([by[h][k]["trst"] / by[h][k]["exst"] for k in both])) for h in by} if both else {}
        out["both"] = {
            "n": len(both),
            "length_mean_m": {BASELINE: float(la.mean()), other: float(lb.mean())} if both else {},
            "length_diff_m": float((lb - la).mean()) if both else math.nan,
            "length_diff_ci_m": t_interval(lb - la),
            "efficiency": eff,
        }
    return out


def _pct(x: float) -> str:
    return f"{100 * x:.2f}"


def markdown(summary: dict) -> str:
    """The study's table (ours beside the thesis's numbers)."""
    n = summary["trials"]
    cov = summary.get("coverage")
    cov_s = (
        f"; mean mission-area coverage by the margined cells {_pct(cov['issue'])} % at issue, "
        f"{_pct(cov['horizon'])} % after 1 h (thesis 18.2 %, 26.4 %)"
        if cov
        else ""
    )
    lines = [
        f"{n} trials on {summary['fields']} synthetic fields{cov_s}; 95 % intervals (success: Wilson; "
        "runtime: t; ratio: paired bootstrap)",
        "",
        "| heuristic | success [%] | thesis | success ≤ 20 EXST [%] | thesis | mean EXST (successes) "
        "| TRST/EXST (successes) [%] | runtime mean [s] | runtime / EDH |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for h, e in summary["heuristics"].items():
        th = THESIS.get(h, {})
        lo, hi = e["success_ci"]
        flo, fhi = e["fast_ci"]
        rlo, rhi = e["runtime_ci_s"]
        ratio = e.get("runtime_ratio")
        ratio_s = f"{ratio[0]:.2f} [{ratio[1]:.2f}, {ratio[2]:.2f}]" if ratio else "1 (baseline)"
        lines.append(
            f"| {h.upper()} | {_pct(e['success'] / e['n'])} [{_pct(lo)}, {_pct(hi)}] | {th.get('success', '–')} "
            f"| {_pct(e['fast_success'] / e['n'])} [{_pct(flo)}, {_pct(fhi)}] | {th.get('fast', '–')} "
            f"| {e['exst_mean_ok']:.1f} | {_pct(e['efficiency_ok'])} "
            f"| {e['runtime_mean_s']:.2f} [{rlo:.2f}, {rhi:.2f}] | {ratio_s} |"
        )
    errors = {h: e["errors"] for h, e in summary["heuristics"].items() if e["errors"]}
    if errors:
        lines += [
            "",
            "Planner exceptions (counted as failures): "
            + ", ".join(f"{h.upper()} {k}" for h, k in errors.items())
            + " (trials.csv: status `error: ...`).",
        ]
    lines += [
        "",
        f"Every heuristic ends in the same state with the same EXST and length in {summary['same_search']} "
        f"of {n} trials.",
    ]
    both = summary.get("both")
    if both and both["n"]:
        lo, hi = both["length_diff_ci_m"]
        lens = ", ".join(f"{h.upper()} {v / 1000:.2f} km" for h, v in both["length_mean_m"].items())
        effs = ", ".join(f"{h.upper()} {_pct(v)} %" for h, v in both["efficiency"].items())
        lines += [
            "",
            f"Both succeed in {both['n']} of {n} trials (thesis: 7760 of 10000). Mean length there: {lens} "
            f"(thesis: EDH 135.97 km, SSPH +0.79 m); SSPH − EDH {both['length_diff_m']:.1f} m "
            f"[{lo:.1f}, {hi:.1f}]. TRST/EXST there: {effs} (thesis: EDH 85.07 %, SSPH 93.74 %).",
        ]
    return "\n".join(lines)
