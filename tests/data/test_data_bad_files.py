"""Bad files are rejected whole, with file, line, column, value and what was expected."""

from __future__ import annotations

import pytest

from surrogate.data import DataFileError, load_any, load_bench_log, load_cfd_samples


def _write(tmp_path, name: str, lines: list[str]) -> str:
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def _set_cell(lines: list[str], line: int, column: str, value: str) -> list[str]:
    """Copy of ``lines`` with one cell replaced (``line`` is 1-based, as in the file)."""
    header = lines[0].split(",")
    out = list(lines)
    cells = out[line - 1].split(",")
    cells[header.index(column)] = value
    out[line - 1] = ",".join(cells)
    return out


def _drop_column(lines: list[str], column: str) -> list[str]:
    index = lines[0].split(",").index(column)
    return [",".join(c for i, c in enumerate(row.split(",")) if i != index) for row in lines]


def _rejected(load, path) -> DataFileError:
    with pytest.raises(DataFileError) as caught:
        load(path)
    return caught.value


# (kind of bad file, how to make it from the good CFD lines, line, column, words in the message)
CFD_CASES = [
    ("text in a number column", lambda l: _set_cell(l, 7, "q_lpm", "abc"), 7, "q_lpm",
     "'abc', expected a number"),
    ("missing column", lambda l: _drop_column(l, "p_B_bar"), 1, "p_B_bar", "missing"),
    ("extra column", lambda l: [l[0] + ",mesh"] + [r + ",fine" for r in l[1:]], 1, "mesh",
     "only the documented columns"),
    ("misspelt column", lambda l: [l[0].replace("q_lpm", "Q_lpm")] + l[1:], 1, "Q_lpm",
     "did you mean 'q_lpm'"),
    ("non-finite value", lambda l: _set_cell(l, 4, "f_sim_N", "inf"), 4, "f_sim_N",
     "a finite number"),
    ("NaN value", lambda l: _set_cell(l, 5, "p_L_bar", "NaN"), 5, "p_L_bar", "a finite number"),
    ("empty cell", lambda l: _set_cell(l, 3, "rho_kg_m3", ""), 3, "rho_kg_m3", "empty"),
    ("negative opening", lambda l: _set_cell(l, 6, "u_mm", "-0.05"), 6, "u_mm", "0 to 100 mm"),
    ("negative flow", lambda l: _set_cell(l, 8, "q_lpm", "-1.0"), 8, "q_lpm", "0 to 5000 L/min"),
    ("zero viscosity", lambda l: _set_cell(l, 9, "nu_cSt", "0"), 9, "nu_cSt", "0.1 to 100000 cSt"),
    ("density out of range", lambda l: _set_cell(l, 10, "rho_kg_m3", "86.9"), 10, "rho_kg_m3",
     "600 to 1200"),
    ("temperature out of range", lambda l: _set_cell(l, 11, "temperature_C", "293.15"), 11,
     "temperature_C", "-40 to 200"),
    ("load below back pressure", lambda l: _set_cell(l, 12, "p_L_bar", "4.0"), 12, "p_L_bar",
     "load pressure >= back pressure"),
    ("duplicate case id", lambda l: _set_cell(l, 13, "case", "C0002"), 13, "case",
     "already on line 3"),
    ("decimal comma", lambda l: _set_cell(l, 2, "u_mm", '"0,05"'), 2, "u_mm", "decimal point"),
    ("pressure below vacuum", lambda l: _set_cell(l, 3, "p_B_bar", "-2"), 3, "p_B_bar",
     "-1.013 to 1000 bar"),
    ("row with too few fields", lambda l: l[:5] + [",".join(l[5].split(",")[:-1])] + l[6:], 6,
     None, "10 comma-separated fields"),
]


@pytest.mark.parametrize("kind, corrupt, line, column, words", CFD_CASES,
                         ids=[case[0] for case in CFD_CASES])
def test_bad_cfd_file_is_rejected_with_its_place(tmp_path, cfd_lines, kind, corrupt, line,
                                                 column, words):
    path = _write(tmp_path, "samples.csv", corrupt(cfd_lines))
    error = _rejected(load_cfd_samples, path)
    message = str(error)
    place = f"{path}, line {line}" + (f", column '{column}'" if column else "")
    assert place in message, message
    assert words in message, message


BENCH_CASES = [
    ("unknown direction", lambda l: _set_cell(l, 5, "direction", "rising"), 5, "direction",
     "'up', 'down'"),
    ("time not increasing", lambda l: _set_cell(l, 9, "time_s", "1.7"), 9, "time_s",
     "time increasing within run 'R01'"),
    ("set point changes within a run", lambda l: _set_cell(l, 6, "p_Pe_nominal_bar", "65"), 6,
     "p_Pe_nominal_bar", "one set point per run"),
    ("missing run id", lambda l: _set_cell(l, 4, "run", ""), 4, "run", "empty"),
]


@pytest.mark.parametrize("kind, corrupt, line, column, words", BENCH_CASES,
                         ids=[case[0] for case in BENCH_CASES])
def test_bad_bench_log_is_rejected_with_its_place(tmp_path, bench_lines, kind, corrupt, line,
                                                  column, words):
    path = _write(tmp_path, "bench.csv", corrupt(bench_lines))
    message = str(_rejected(load_bench_log, path))
    assert f"{path}, line {line}, column '{column}'" in message, message
    assert words in message, message


WHOLE_FILE_CASES = [
    ("empty file", b"", "the file is empty"),
    ("blank lines only", b"\n  \n\n", "the file is empty"),
    ("binary file", b"PK\x03\x04\x00\x00\x14\x00binary spreadsheet", "binary"),
    ("not UTF-8", b"case,oil\nC1,\xe9l\xe8ve\n", "UTF-8"),
    ("tab separated", b"case\toil\ttemperature_C\nC1\tx\t20\n", "separated by tabs"),
    ("JSON, not CSV", b'{"case": "C1", "u_mm": 0.1}\n', "not a CSV file"),
    ("unrelated CSV", b"name,age,city\nAnn,31,Oslo\n", "the header of a CFD-sample file"),
]


@pytest.mark.parametrize("kind, content, words", WHOLE_FILE_CASES,
                         ids=[case[0] for case in WHOLE_FILE_CASES])
def test_file_that_is_not_a_data_file_is_rejected(tmp_path, kind, content, words):
    path = tmp_path / "input.csv"
    path.write_bytes(content)
    message = str(_rejected(load_any, path))
    assert str(path) in message and words in message, message


def test_header_only_file_is_rejected(tmp_path, cfd_lines):
    path = _write(tmp_path, "header.csv", cfd_lines[:1])
    assert "found none" in str(_rejected(load_cfd_samples, path))


def test_bench_log_is_not_accepted_as_cfd_samples(tmp_path, bench_lines):
    path = _write(tmp_path, "bench.csv", bench_lines)
    message = str(_rejected(load_cfd_samples, path))
    assert "a CFD-sample file; this header is that of a bench log" in message


def test_several_problems_are_reported_together_in_file_order(tmp_path, cfd_lines):
    lines = _set_cell(cfd_lines, 9, "u_mm", "-1")
    lines = _set_cell(lines, 4, "q_lpm", "x")
    lines = _set_cell(lines, 12, "case", "C0001")
    error = _rejected(load_cfd_samples, _write(tmp_path, "multi.csv", lines))
    assert [(p.line, p.column) for p in error.problems] == [(4, "q_lpm"), (9, "u_mm"),
                                                            (12, "case")]
    assert "3 problems" in str(error)


def test_problem_records_value_and_expectation(tmp_path, cfd_lines):
    error = _rejected(load_cfd_samples,
                      _write(tmp_path, "v.csv", _set_cell(cfd_lines, 7, "q_lpm", "lots")))
    (problem,) = error.problems
    assert (problem.line, problem.column, problem.value) == (7, "q_lpm", "lots")
    assert "L/min" in problem.expected


def test_line_numbers_count_blank_lines_and_crlf(tmp_path, cfd_lines):
    lines = _set_cell(cfd_lines, 5, "q_lpm", "?")
    text = "\r\n".join(lines[:3] + [""] + lines[3:]) + "\r\n"  # a blank line before file line 4
    path = tmp_path / "crlf.csv"
    path.write_bytes(text.encode())
    (problem,) = _rejected(load_cfd_samples, path).problems
    assert problem.line == 6  # line 5 of the original moved down by the blank line


def test_byte_order_mark_is_accepted(tmp_path, cfd_lines):
    path = tmp_path / "bom.csv"
    path.write_bytes(("\ufeff" + "\n".join(cfd_lines) + "\n").encode("utf-8"))
    assert len(load_cfd_samples(path)) == len(cfd_lines) - 1
