"""The columnar reader gives what the exact (cell-by-cell) reader gives: the same values and the
same problems, in the same order, for good files and for every corruption of the fuzz suite."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_fuzz import BAD_NUMBERS, CASES, CFD, LOG, PSI, in_unit, semicolons, set_cell

from surrogate.data import reader
from surrogate.data.errors import DataFileError
from surrogate.data.loaders import load_any


def _load(path, exact: bool, monkeypatch):
    with monkeypatch.context() as patch:
        if exact:
            patch.setattr(reader, "_columnar_table", lambda *args: None)
        try:
            return load_any(path), None
        except DataFileError as error:
            return None, error


def _same(path, monkeypatch):
    table, error = _load(path, False, monkeypatch)
    exact_table, exact_error = _load(path, True, monkeypatch)
    if exact_error is not None or error is not None:
        assert error is not None and exact_error is not None
        assert [vars(p) for p in error.problems] == [vars(p) for p in exact_error.problems]
        return
    assert table.frame.equals(exact_table.frame)


TEXTS = [case.files["bad.csv"] for case in CASES
         if case.argv[:1] == ("check-data",) and isinstance(case.files.get("bad.csv"), str)]
TEXTS += [case.files["log.csv"] for case in CASES if isinstance(case.files.get("log.csv"), str)]


@pytest.mark.parametrize("index", range(len(TEXTS)))
def test_both_readers_agree_on_every_fuzz_file(index, tmp_path, monkeypatch):
    path = tmp_path / "file.csv"
    path.write_text(TEXTS[index])
    _same(path, monkeypatch)


@pytest.mark.parametrize("text", [LOG, CFD, "\n\n\n" + LOG, LOG.replace("\n", "\r\n"),
                                  LOG + "\n\n", "\ufeff" + LOG, semicolons(LOG),
                                  "\ufeff\n" + semicolons(LOG).replace("\n", "\r\n"),
                                  in_unit(LOG, "p_L_bar", "p_L_psi", lambda v: v * PSI)],
                         ids=["log", "cfd", "blank lines first", "CRLF", "blank lines last",
                              "byte-order mark", "semicolons", "semicolons, BOM, CRLF", "psi"])
def test_both_readers_agree_on_good_files(text, tmp_path, monkeypatch):
    path = tmp_path / "file.csv"
    path.write_text(text, encoding="utf-8")
    _same(path, monkeypatch)
    assert _load(path, False, monkeypatch)[1] is None


@settings(max_examples=30, deadline=None)
@given(line=st.integers(2, 60), value=BAD_NUMBERS, data=st.data())
def test_both_readers_agree_on_generated_bad_cells(line, value, data, tmp_path_factory):
    columns = [c for c in LOG.splitlines()[0].split(",") if c.endswith(("_bar", "_lpm", "_C"))]
    path = tmp_path_factory.mktemp("cells") / "log.csv"
    path.write_text(set_cell(LOG, line, data.draw(st.sampled_from(columns)), value))
    with pytest.MonkeyPatch.context() as monkeypatch:
        _same(path, monkeypatch)


def test_a_header_after_blank_lines_is_reported_at_its_own_line(tmp_path):
    path = tmp_path / "log.csv"
    path.write_text("\n\n\n" + LOG.replace("q_lpm", "Q_lpm", 1))
    with pytest.raises(DataFileError) as caught:
        load_any(path)
    assert "line 4" in str(caught.value) and "line 1," not in str(caught.value)


def test_the_columnar_reader_keeps_each_rows_own_line(tmp_path):
    lines = LOG.splitlines()
    path = tmp_path / "log.csv"
    path.write_text("\n".join([lines[0], "", lines[1], "", "", *lines[2:]]) + "\n")
    table = load_any(path)
    assert list(table.frame["line"][:4]) == [3, 6, 7, 8]
