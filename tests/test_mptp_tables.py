"""docs/mptp.md's generated tables reproduce: key rows recomputed by the generating code
(sim/testbeds/mptp_tables.py) must equal the rows in the document, to the printed digit."""

import pytest

from sim.testbeds import mptp_tables as T
from sim.testbeds import mptp_thesis as S


def _row(table: str, *cells: str) -> str:
    """The line of a Markdown table whose first cells are ``cells``."""
    lines = [ln for ln in table.splitlines() if ln.startswith("| " + " | ".join(cells) + " |")]
    assert len(lines) == 1, f"no single row {cells} in {table!r}"
    return lines[0]


@pytest.mark.parametrize("make", [S.scenario_2, S.holding_scenario], ids=["scenario2", "holding"])
def test_openloop_rows_reproduce(make):
    row = T.openloop_row(make)
    doc = T.generated(T.DOC.read_text(), "openloop")
    assert T.openloop_table([row]).splitlines()[-1] == _row(doc, row["scenario"])


def test_heuristics_rows_reproduce():
    doc = T.generated(T.DOC.read_text(), "heuristics")
    for heuristic in ("edh", "ssph"):
        row = T.heuristics_row(S.scenario_2, heuristic, "right")
        assert T.heuristics_table([row]).splitlines()[-1] == _row(doc, "scenario 2", "right", heuristic)


def test_generated_tables_are_replaced_between_their_markers():
    text = "a\n<!-- generated: x -->\nold\n<!-- end generated -->\nb\n"
    new = T.replace_generated(text, "x", "| new |")
    assert T.generated(new, "x") == "| new |" and new.startswith("a\n") and new.endswith("b\n")
    with pytest.raises(KeyError, match="no generated table 'y'"):
        T.replace_generated(text, "y", "")
