"""``python -m surrogate check-data``: summary and exit 0 on good files, errors and exit 2 on bad."""

import json
import subprocess
import sys

import pytest

from surrogate.cli import main
from surrogate.core.paths import PROJECT_ROOT, SHIPPED_BENCH_LOG, SHIPPED_CFD_SAMPLES

pytestmark = pytest.mark.pipeline  # every test here runs a command end to end

def test_shipped_cfd_samples_summary(capsys):
    assert main(["check-data", str(SHIPPED_CFD_SAMPLES)]) == 0
    out = capsys.readouterr().out
    assert "CFD samples, 154 rows" in out
    assert "0.05, 0.08, 0.1, 0.13, 0.16, 0.2, 0.63 mm" in out
    assert "20 °C" in out and "60 °C" in out


def test_shipped_bench_log_summary_lists_runs_and_set_points(capsys):
    assert main(["check-data", str(SHIPPED_BENCH_LOG), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["kind"] == "bench_log" and summary["rows"] == 11000
    assert [r["p_Pe_nominal_bar"] for r in summary["runs"][:4]] == [50, 65, 80, 120]


def test_text_in_flow_on_line_7_exits_2_naming_file_line_and_column(tmp_path, cfd_lines, capsys):
    lines = list(cfd_lines)
    cells = lines[6].split(",")
    cells[6] = "twelve"
    lines[6] = ",".join(cells)
    path = tmp_path / "bad.csv"
    path.write_text("\n".join(lines) + "\n")
    assert main(["check-data", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"{path}, line 7, column 'q_lpm': got 'twelve'" in err


def test_missing_back_pressure_column_exits_2(tmp_path, cfd_lines, capsys):
    index = cfd_lines[0].split(",").index("p_B_bar")
    lines = [",".join(c for i, c in enumerate(row.split(",")) if i != index) for row in cfd_lines]
    path = tmp_path / "no_pB.csv"
    path.write_text("\n".join(lines) + "\n")
    assert main(["check-data", str(path)]) == 2
    assert f"{path}, line 1, column 'p_B_bar'" in capsys.readouterr().err


def test_module_entry_point_runs_as_a_process():
    done = subprocess.run([sys.executable, "-m", "surrogate", "check-data", "nowhere.csv"],
                          capture_output=True, text=True, cwd=PROJECT_ROOT)
    assert done.returncode == 2
    assert "nowhere.csv" in done.stderr
