"""lumis.study: the CLI's study from Python, its tables returned as the values its CSV files print."""

import csv
import math
import os
import signal
import threading
import time
from pathlib import Path

import pytest

import lumis
from conftest import run_cli

# A study small enough for a test: three integrators, two budgets, K = 3, a 16 x 16 film.
OPTIONS = dict(
    integrators="balance,light,alpha",
    budgets=[4, 8],
    runs=3,
    max_runs=3,
    reference_samples=64,
    block=8,
    overrides={"film.width": 16, "film.height": 16},
    threads=2,
)
CLI_OPTIONS = [
    "--integrators", "balance,light,alpha", "--budgets", "4,8", "--runs", "3", "--max-runs", "3",
    "--reference-samples", "64", "--block", "8", "--set", "film.width=16", "--set", "film.height=16",
    "--threads", "2", "--quiet",
]
# Columns that measure time differ between any two runs of the same study.
TIMED = ("wall_time", "cpu_time", "efficiency", "target_time", "time_to_target", "speedup",
         "equal_time_ratio", "ratio_cpu_time", "ratio_efficiency", "ratio_paper_efficiency")


def timed(column: str) -> bool:
    return column.startswith(TIMED)


def read_csv(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def same_field(text: str, value) -> bool:
    """Whether a CSV field prints `value` (numbers with a fixed number of decimals are rounded
    in the file; every other number is printed with its shortest round-trip digits)."""
    if value is None:
        return text == ""
    if isinstance(value, str):
        return text == value
    if isinstance(value, int):
        return int(text) == value
    if "e" in text or "inf" in text or "NaN" in text:
        return float(text) == value or (math.isnan(value) and text == "NaN")
    return math.isclose(float(text), value, rel_tol=0, abs_tol=0.6 * 10.0 ** -len(text.split(".")[-1]))


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("study")
    calls = []
    result = lumis.study(
        Path(__file__).resolve().parents[2] / "scenes" / "veach.ron",
        out,
        progress=lambda done, total, message: calls.append((done, total, message)),
        **OPTIONS,
    )
    return result, calls


def test_tables_are_the_csv_files(study):
    result, _ = study
    assert isinstance(result, lumis.Study)
    for table, file in [(result.results, "results.csv"), (result.trade, "trade.csv")]:
        written = read_csv(result.out / file)
        assert len(table) == len(written) > 0
        for row, line in zip(table, written):
            assert list(row) == list(line)
            for column, text in line.items():
                assert same_field(text, row[column]), (file, column, text, row[column])
    # Three integrators at two budgets.
    assert {(r["integrator"], r["samples"]) for r in result.results if r["group"] == "curve"} == {
        (i, n) for i in ["balance", "light", "alpha"] for n in [4, 8]
    }
    assert result.report == result.out / "results.md" and result.report.is_file()


def test_curves_are_the_curve_rows(study):
    result, _ = study
    rows = {(r["integrator"], r["samples"]): r for r in result.results if r["group"] == "curve"}
    assert len(result.curves) == len(rows)
    for point in result.curves:
        row = rows[(point["integrator"], point["samples"])]
        for name in ["relative_variance", "relative_mse", "cpu_time"]:
            assert point[f"{name}_lo"] <= point[name] <= point[f"{name}_hi"]
            assert (point[name], point[f"{name}_lo"], point[f"{name}_hi"]) == (
                row[name], row[f"{name}_lo"], row[f"{name}_hi"]
            )


def test_progress_reaches_the_total(study):
    _, calls = study
    assert calls, "progress was never called"
    done = [c[0] for c in calls]
    assert done == sorted(done)
    assert calls[-1][0] == calls[-1][1] > 0


def test_same_numbers_as_the_cli(cli, study, tmp_path):
    result, _ = study
    scene = Path(__file__).resolve().parents[2] / "scenes" / "veach.ron"
    out = tmp_path / "cli"
    ran = run_cli(cli, "study", str(scene), "-o", str(out), *CLI_OPTIONS, cwd=tmp_path)
    assert ran.returncode == 0, ran.stderr
    for table, file in [(result.results, "results.csv"), (result.trade, "trade.csv")]:
        lines = read_csv(out / file)
        assert len(lines) == len(table)
        for row, line in zip(table, lines):
            for column, text in line.items():
                if not timed(column):
                    assert same_field(text, row[column]), (file, column, text, row[column])


def test_dataframe(study):
    pandas = pytest.importorskip("pandas")
    result, _ = study
    frame = result.dataframe()
    assert isinstance(frame, pandas.DataFrame)
    assert frame.shape == (len(result.results), len(result.results[0]))
    assert list(result.dataframe("curves").columns)[:3] == ["scene", "integrator", "samples"]
    with pytest.raises(ValueError, match="results, trade, curves"):
        result.dataframe("rows")


def test_refused_options_raise_the_clis_messages(tmp_path, small_scene):
    with pytest.raises(ValueError, match="must include `balance`"):
        lumis.study(small_scene, tmp_path, integrators=["light", "alpha"])
    with pytest.raises(ValueError, match="--runs must be at least 3"):
        lumis.study(small_scene, tmp_path, runs=2)
    with pytest.raises(ValueError, match="unknown sweep `sideways`"):
        lumis.study(small_scene, tmp_path, sweeps="sideways")
    with pytest.raises(lumis.SceneError, match="missing.ron"):
        lumis.study(tmp_path / "missing.ron", tmp_path / "out", **OPTIONS)


def test_an_exception_in_progress_stops_the_study(tmp_path, small_scene):
    def stop(done, total, message):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        lumis.study(small_scene, tmp_path, progress=stop, **OPTIONS)


@pytest.mark.skipif(os.name != "posix", reason="sends SIGINT")
def test_ctrl_c_interrupts_the_study(tmp_path, python_sigint_handler):
    scene = Path(__file__).resolve().parents[2] / "scenes" / "veach.ron"
    # Minutes of work on two cores (a reference of 2^20 samples per light per pixel): only an
    # interrupt ends it within the test.
    timer = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        lumis.study(scene, tmp_path, **{**OPTIONS, "reference_samples": 1 << 20})
    timer.join()
    assert time.monotonic() - start < 30
