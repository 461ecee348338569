"""``tune_main``: tables and files, exit 2 with a one-line error on bad input."""

import json

from sim.tuning.cli import tune_main


def test_linearize_writes_model(tmp_path, capsys):
    assert tune_main(["linearize", "haps", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "short period" in out and "Dutch roll" in out
    data = json.loads(next(tmp_path.glob("linear_haps_*.json")).read_text())
    assert len(data["A"]) == 10 and len(data["modes"]) == 5


def test_margins_haps(tmp_path, capsys):
    assert tune_main(["margins", "haps", "--out", str(tmp_path)]) == 0
    rows = json.loads((tmp_path / "margins_haps.json").read_text())
    assert [r["name"] for r in rows] == ["roll", "pitch", "tecs-pitch", "tecs-throttle"]
    assert all(r["phase_margin_deg"] > 0 and r["jsbsim_overshoot_pct"] > 0 and not r["warning"] for r in rows)


def test_margins_quadrotor_without_steps(tmp_path, capsys):
    assert tune_main(["margins", "quadrotor", "--no-steps", "--out", str(tmp_path)]) == 0
    rows = json.loads((tmp_path / "margins_quadrotor.json").read_text())
    names = ["rate", "attitude", "velocity", "position", "yaw-rate", "yaw", "climb-rate", "altitude"]
    assert [r["name"] for r in rows] == names
    assert all("jsbsim_overshoot_pct" not in r for r in rows)


def test_bad_inputs_exit_2(capsys):
    for argv in (
        ["trim", "plane"],
        ["linearize", "haps", "--alt", "21000", "--tas", "20"],
        ["margins", "haps", "--tas", "-3"],
        ["bogus"],
        ["roll-gain"],
        ["gain", "quadrotor", "roll", "--phase-margin", "45"],
        ["gain", "haps", "roll", "--phase-margin", "45", "--crossover", "3"],
        ["gain", "haps", "roll", "--phase-margin", "190"],
        ["linearize", "quadrotor"],
    ):
        assert tune_main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert err.startswith("error:") and "\n" not in err, (argv, err)
