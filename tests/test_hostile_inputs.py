"""Hostile input: every bad scenario file, batch file, log file or output folder gives one line
naming the file and exit status 2 (no traceback); fuzz tests (hypothesis) of random TOML
structures, random bytes, mutated real MCAPs and foreign MCAPs with cosim's topic names, in which
nothing raises but the project's own errors."""

import contextlib
import copy
import json
import os
import tomllib
from pathlib import Path

import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.writer import Writer

from sim.batch import BatchError, load_batch
from sim.cli import main
from sim.input_files import MAX_BYTES
from sim.mcap_read import LogReadError, read_info
from sim.output_paths import OutputPathError, path_under
from sim.replay.report import log_metrics, write_report
from sim.replay.runlog import RunLog
from sim.runner import RunFailed, run_scenario
from sim.scenario import ScenarioError, load_scenario, parse_scenario

ROOT = Path(__file__).resolve().parents[1]
QUAD = ROOT / "scenarios" / "quad_square_mission.toml"
QUAD_DATA = tomllib.loads(QUAD.read_text())


def one_line_exit_2(capsys, argv: list[str], expected: str) -> str:
    """Run the CLI in-process; assert exit 2 and one stderr line containing ``expected``."""
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert expected in err, err
    return err


# -- scenario files ------------------------------------------------------------------------------
def _bytes_cases(tmp: Path) -> list[tuple[Path, str]]:
    text = QUAD.read_text()
    cases = {
        "latin1.toml": (text.replace('description = "', 'description = "caf\xe9 ').encode("latin-1"), "is not UTF-8"),
        "utf16.toml": (text.encode("utf-16"), "UTF-16-encoded; save it as UTF-8"),
        "utf32.toml": (text.encode("utf-32"), "UTF-32-encoded"),
        "deep_arrays.toml": (("a = " + "[" * 5000 + "]" * 5000).encode(), "TOML nested"),
        "deep_tables.toml": (("a = " + "{x = " * 40 + "1" + "}" * 40).encode(), "TOML nested more than 32"),
        "huge.toml": (b"# " + b"x" * (MAX_BYTES + 10), "more than the 4194304 allowed"),
        "nul.toml": (b"name = \x00", "not valid TOML"),
    }
    out = []
    for name, (data, expected) in cases.items():
        (tmp / name).write_bytes(data)
        out.append((tmp / name, expected))
    fifo = tmp / "fifo.toml"
    os.mkfifo(fifo)  # reading it would block forever
    out += [(fifo, "is not a regular file"), (Path("/dev/zero"), "is not a regular file"), (tmp, "not a regular file")]
    return out


@pytest.mark.parametrize("command", ["validate", "run"])
def test_unreadable_scenario_files_are_one_line_errors(tmp_path, capsys, command):
    for path, expected in _bytes_cases(tmp_path):
        err = one_line_exit_2(
            capsys, [command, str(path), "-q"] if command == "run" else [command, str(path)], expected
        )
        assert err.startswith(f"error: {path}: ")


@pytest.mark.parametrize("name", ["../../x", "/abs/x", "a/b", "..", ".hidden", "a\\b", ""])
def test_scenario_name_must_be_a_name(tmp_path, capsys, monkeypatch, name):
    f = tmp_path / "s.toml"
    f.write_text(tomli_w.dumps({**QUAD_DATA, "name": name}))
    monkeypatch.chdir(tmp_path)
    one_line_exit_2(capsys, ["run", str(f), "-q"], "name: ")
    assert list(tmp_path.iterdir()) == [f]  # nothing written anywhere


def test_output_paths_stay_under_their_folder(tmp_path):
    assert path_under(tmp_path, "run.mcap") == tmp_path / "run.mcap"
    for bad in ("../x.mcap", "/abs/x.mcap", "a/../../x", ".."):
        with pytest.raises(OutputPathError, match="must not leave"):
            path_under(tmp_path, bad)


def test_failure_before_the_first_log_tick_is_reported_as_itself(tmp_path):
    """Was ``KeyError: 'turning'`` from the metrics of vehicles that never logged (two
    vehicles: the separation metrics need (0, 3) position arrays too)."""
    data = tomllib.loads((ROOT / "scenarios" / "mixed_haps_quad.toml").read_text())
    data["mavlink"] = {"enabled": True, "gcs_host": "no-such-host.invalid"}
    with pytest.raises(RunFailed) as info:
        run_scenario(parse_scenario(data, "t"), tmp_path / "x.mcap")
    assert info.value.result.error.startswith("ValueError: MAVLink gcs_host 'no-such-host.invalid' does not resolve")
    assert RunLog(tmp_path / "x.mcap").metadata["result"]["status"] == "failed"


def _toml_values():
    scalars = st.one_of(
        st.booleans(),
        st.integers(-(2**63), 2**63 - 1),
        st.floats(allow_nan=True),
        st.text(max_size=12),
        st.sampled_from(["10 m", "5 kt", "1e400 m", "-3 s", "nan m", "90 deg", "x y z"]),
    )
    keys = st.one_of(st.sampled_from([*sorted(QUAD_DATA), "vehicle", "name", "seed", "origin"]), st.text(max_size=8))
    return st.recursive(
        scalars,
        lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(keys, inner, max_size=4)),
        max_leaves=12,
    )


@st.composite
def _mutated_scenarios(draw):
    """The shipped quadrotor scenario with a random value put at a random place (top level,
    a vehicle, its mission or initial state), or a random TOML document."""
    if draw(st.integers(0, 9)) == 0:
        doc = draw(st.dictionaries(st.text(max_size=8), _toml_values(), max_size=6))
        return doc
    doc = copy.deepcopy(QUAD_DATA)
    node = draw(
        st.sampled_from(
            [doc, doc["vehicle"][0], doc["vehicle"][0]["mission"], doc["vehicle"][0]["initial"], doc["origin"]]
        )
    )
    key = draw(st.one_of(st.sampled_from(sorted(node)), st.text(min_size=1, max_size=8)))
    node[key] = draw(_toml_values())
    return doc


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(_mutated_scenarios())
def test_fuzz_random_toml_scenarios_raise_only_scenario_errors(tmp_path, doc):
    f = tmp_path / "fuzz.toml"
    try:
        f.write_text(tomli_w.dumps(doc))
    except (TypeError, ValueError):  # not representable as TOML (e.g. a NaN key order issue): not a file
        return
    try:
        load_scenario(f)
    except ScenarioError as exc:
        assert "\n" not in str(exc) and str(exc).startswith(f"{f}: ")


# -- batch files -----------------------------------------------------------------------------------
BASE = f'base = "{QUAD}"\n'


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ('base = "x.toml"\nbogus = 1\n', "bogus: unknown key"),
        ('name = "x"\n', "base: missing required field"),
        ('base = "nope.toml"\n', "base: cannot load"),
        ("base = 1\n", "base: Input should be a valid string"),
        (BASE + 'name = "../../escape"\n', "name: '../../escape' is not a name"),
        (BASE + "sweep = 3\n", "sweep: Input should be a valid dictionary"),
        (BASE + '[sweep]\n"seed" = []\n', "sweep.seed: List should have at least 1 item"),
        (BASE + '[monte_carlo]\nruns = "many"\n', "monte_carlo.runs: Input should be a valid integer"),
        (BASE + "[monte_carlo]\nruns = 0\n", "monte_carlo.runs"),
        (BASE + '[monte_carlo.uniform]\n"seed" = [1]\n', "monte_carlo.uniform.seed"),
        (BASE + '[monte_carlo.normal]\n"seed" = [1, -2]\n', "monte_carlo.normal.seed[1]: out of range"),
        (BASE + '[monte_carlo]\nruns = 100000\n[sweep]\n"seed" = [1, 2]\n', "more than 100000 runs"),
        (BASE + 'duration = "ten minutes"\n', "duration"),
        (BASE + '[sweep]\n"vehicle.7.name" = ["x"]\n', "vehicle.7.name: no such field"),
    ],
)
def test_bad_batch_files(tmp_path, capsys, text, expected):
    f = tmp_path / "b.toml"
    f.write_text(text)
    with pytest.raises(BatchError, match=None) as info:
        load_batch(f, tmp_path / "out")
    assert expected in str(info.value) and "\n" not in str(info.value)
    one_line_exit_2(capsys, ["batch", str(f), "-o", str(tmp_path / "out"), "-q"], expected)


def test_unreadable_batch_and_base_files(tmp_path, capsys):
    for path, expected in _bytes_cases(tmp_path):
        one_line_exit_2(capsys, ["batch", str(path), "-q"], expected)
    (tmp_path / "b.toml").write_text('base = "/dev/zero"\n')
    one_line_exit_2(capsys, ["batch", str(tmp_path / "b.toml"), "-q"], "base: cannot load /dev/zero: base scenario")


# -- logs ------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def real_log(tmp_path_factory) -> Path:
    """A short real run log (quadrotor, 2 s)."""
    path = tmp_path_factory.mktemp("log") / "quad.mcap"
    run_scenario(parse_scenario({**QUAD_DATA, "duration": 2.0}, "quad"), path)
    return path


def _read_everything(path: Path, out: Path) -> None:
    """What info, compare and replay do with a log; only the project's errors may escape."""
    with contextlib.suppress(LogReadError):
        read_info(path)
    try:
        log_metrics(RunLog(path))
        write_report(path, out)
    except (LogReadError, ScenarioError):
        pass


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.binary(max_size=4096))
def test_fuzz_random_bytes_as_a_log(tmp_path, data):
    f = tmp_path / "random.mcap"
    f.write_bytes(b"\x89MCAP0\r\n" + data if data[:1] == b"\x00" else data)
    _read_everything(f, tmp_path / "rep")


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_fuzz_mutated_real_logs(tmp_path, real_log, data):
    buf = bytearray(real_log.read_bytes())
    for _ in range(data.draw(st.integers(1, 6))):
        op = data.draw(st.sampled_from(["flip", "overwrite", "truncate", "cut"]))
        i = data.draw(st.integers(0, len(buf) - 1))
        if op == "flip":
            buf[i] ^= data.draw(st.integers(1, 255))
        elif op == "overwrite":
            chunk = data.draw(st.binary(min_size=1, max_size=64))
            buf[i : i + len(chunk)] = chunk
        elif op == "truncate":
            del buf[i:]
        else:
            del buf[i : i + data.draw(st.integers(1, 256))]
        if not buf:
            break
    f = tmp_path / "mutated.mcap"
    f.write_bytes(bytes(buf))
    _read_everything(f, tmp_path / "rep")


_JSON = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(), st.floats(allow_nan=False), st.text(max_size=5)),
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=4)),
    max_leaves=12,
)


@st.composite
def _foreign_messages(draw, real: dict):
    """A message shaped like a real one with random keys dropped or values replaced."""
    msg = dict(real)
    for key in draw(st.lists(st.sampled_from(sorted(real)), max_size=4, unique=True)):
        if draw(st.booleans()):
            del msg[key]
        else:
            msg[key] = draw(_JSON)
    return msg


@pytest.fixture(scope="module")
def real_messages(real_log) -> dict[str, dict]:
    """One JSON message of each JSON topic of the real log."""
    log = RunLog(real_log)
    return {t: log.topic(t).messages[0] for t in log.topics if isinstance(log.topic(t).messages[0], dict)}


@settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_fuzz_foreign_logs_with_cosim_topics(tmp_path, real_messages, data):
    """A valid MCAP that is not cosim's: cosim's topic names with messages missing fields or
    holding wrong types, and edited metadata."""
    f = tmp_path / "foreign.mcap"
    with open(f, "wb") as stream:
        w = Writer(stream)
        w.start("foreign", "hypothesis")
        w.add_metadata("run", {"epoch_ns": data.draw(st.sampled_from(["0", "x", "1e9"]))})
        schema = w.register_schema("s", "jsonschema", b"{}")
        for topic, real in real_messages.items():
            ch = w.register_channel(topic, "json", schema)
            for k in range(data.draw(st.integers(1, 3))):
                msg = data.draw(_foreign_messages(real))
                w.add_message(ch, log_time=k * 100_000_000, data=json.dumps(msg).encode(), publish_time=0)
        w.finish()
    _read_everything(f, tmp_path / "rep")


def test_corrupt_logs_are_one_line_errors_in_every_command(tmp_path, capsys, real_log):
    data = bytearray(real_log.read_bytes())
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(bytes(data[: len(data) // 2]) + bytes(200) + bytes(data[len(data) // 2 :]))
    foreign = tmp_path / "foreign.mcap"
    foreign.write_bytes(b"not an mcap at all")
    for path in (damaged, foreign):
        one_line_exit_2(capsys, ["info", str(path)], str(path))
        one_line_exit_2(capsys, ["replay", str(path), "-o", str(tmp_path / "rep")], str(path))
        one_line_exit_2(capsys, ["compare", str(real_log), str(path)], str(path))
    from sim.mavlink.replay import main as mavlink_replay

    for path in (damaged, foreign):
        assert mavlink_replay([str(path), "--speed", "0", "--port", "14999"]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and str(path) in err and "Traceback" not in err


def test_unwritable_output_folders_are_one_line_errors(tmp_path, capsys, real_log):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    one_line_exit_2(capsys, ["replay", str(real_log), "-o", str(blocker / "report")], str(blocker))
    batch = tmp_path / "b.toml"
    batch.write_text(BASE + 'duration = "1 s"\n')
    one_line_exit_2(capsys, ["batch", str(batch), "-o", str(blocker / "out"), "-q"], str(blocker))
