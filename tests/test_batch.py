"""Batch runs: Monte-Carlo on a process pool and on a Dask LocalCluster, resume, failures."""

from pathlib import Path

import pytest

from sim.batch import BatchError, load_batch, run_batch

ROOT = Path(__file__).resolve().parents[1]
MC = ROOT / "scenarios" / "batch" / "haps_monte_carlo.toml"
pytestmark = pytest.mark.closed_loop
FLOWN = 4  # runs of the Monte-Carlo batch flown on each executor


def _deterministic(row: dict) -> dict:
    return {k: v for k, v in row.items() if "planner_latency" not in k}


def _short_batch(tmp_path: Path, extra: str = "", runs: int = 20) -> Path:
    f = tmp_path / "mc.toml"
    f.write_text(
        MC.read_text()
        .replace('base = "../haps_box_mission.toml"', f'base = "{ROOT / "scenarios" / "haps_box_mission.toml"}"')
        .replace('duration = "5 min"', 'duration = "20 s"')
        .replace("runs = 20", f"runs = {runs}")
        + extra
    )
    return f


def test_monte_carlo_same_results_on_process_pool_and_dask(tmp_path):
    """The shipped 20-run batch expands to 20 distinct draws; its first four fly the same rows on
    the process pool and on a Dask cluster (two per worker)."""
    distributed = pytest.importorskip("distributed")
    _name, runs = load_batch(_short_batch(tmp_path), tmp_path / "pool")
    assert len(runs) == 20 and len({r.params["seed"] for r in runs}) == 20
    headings = [r.params["vehicle.0.initial.heading"] for r in runs]
    assert all(-30 <= h <= 30 for h in headings) and len(set(headings)) == 20
    pool_rows = run_batch(runs[:FLOWN], tmp_path / "pool", workers=2)
    assert [r["status"] for r in pool_rows] == ["duration_elapsed"] * FLOWN
    assert (tmp_path / "pool" / "results.csv").read_text().count("\n") == FLOWN + 1

    _, runs_d = load_batch(_short_batch(tmp_path), tmp_path / "dask")
    with (
        distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster,
        distributed.Client(cluster) as client,
    ):
        dask_rows = run_batch(runs_d[:FLOWN], tmp_path / "dask", executor=client.get_executor())
    assert len(dask_rows) == FLOWN
    for a, b in zip(pool_rows, dask_rows, strict=True):
        assert _deterministic(a) == _deterministic(b)
    # different seeds/params give different flights
    finals = {r["metric.vehicles.haps.tracking.max_bank_deg"] for r in pool_rows}
    assert len(finals) == FLOWN


def test_failed_run_is_recorded_and_batch_resumes(tmp_path):
    extra = (
        '\n[sweep]\n"vehicle.0.gains" = ["no_such_gains.toml", "'
        + str(ROOT / "aircraft" / "haps" / "gains.toml")
        + '"]\n'
    )
    _name, runs = load_batch(_short_batch(tmp_path, extra, runs=2), tmp_path / "out")
    assert len(runs) == 4
    rows = run_batch(runs, tmp_path / "out", workers=2)
    status = [r["status"] for r in rows]
    assert status == ["failed", "failed", "duration_elapsed", "duration_elapsed"]
    assert "no_such_gains.toml" in rows[0]["error"]
    assert Path(runs[0].log_path).is_file()  # a failed run still leaves its log
    calls = []
    rows2 = run_batch(runs, tmp_path / "out", workers=1, progress=lambda k, n, row: calls.append(row))
    assert calls == [] and [_deterministic(r) for r in rows2] == [_deterministic(r) for r in rows]


@pytest.mark.parametrize(
    "text,msg",
    [
        ('base = "x.toml"\nbogus = 1\n', "bogus: unknown key"),
        ('name = "x"\n', "base: missing required field"),
        ('base = "nope.toml"\n', "base: cannot load"),
    ],
)
def test_bad_batch_files(tmp_path, text, msg):
    f = tmp_path / "b.toml"
    f.write_text(text)
    with pytest.raises(BatchError, match=msg):
        load_batch(f)


def test_bad_path_in_batch_is_reported_by_scenario_validation(tmp_path):
    extra = '\n[sweep]\n"vehicle.0.initial.altitud" = [1000]\n'
    with pytest.raises(BatchError, match=r"vehicle\[0\]\.initial\.altitud: unknown key"):
        load_batch(_short_batch(tmp_path, extra, runs=1))
