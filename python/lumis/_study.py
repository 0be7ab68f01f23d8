"""`lumis.study`: the speed/accuracy study of `lumis study` (docs/study.md), from Python."""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional, Union

from ._lumis import _study

StrPath = Union[str, "os.PathLike[str]"]
Record = dict[str, Any]


@dataclass(frozen=True)
class Study:
    """What a study measured: its tables as lists of dicts, and where its files are.

    Every number that is an estimate comes with its 95 % interval in the columns ``NAME_lo`` and
    ``NAME_hi``; a value the study has not measured (an integrator without α, say) is None.
    """

    results: list[Record]
    """`results.csv`: one dict per measured configuration (scene, group, integrator, samples,
    runs, statistics and ratios to balance at the same budget)."""
    trade: list[Record]
    """`trade.csv`: per scene and integrator, the time to reach balance's error at the target
    budget, the speed-up over balance and the error ratio at equal time."""
    curves: list[Record]
    """Per scene, integrator and budget: CPU time, relative variance and relative MSE (the
    points of the study's convergence plots)."""
    out: Path
    """The output directory (plots, panels, CSV files, the reference cache)."""
    report: Path
    """The Markdown report."""

    def dataframe(self, table: str = "results"):
        """`table` ("results", "trade" or "curves") as a pandas.DataFrame (needs pandas)."""
        if table not in ("results", "trade", "curves"):
            raise ValueError(f"unknown table {table!r}: the tables are results, trade, curves")
        try:
            import pandas
        except ImportError as e:
            raise ImportError("Study.dataframe needs pandas (pip install pandas)") from e
        return pandas.DataFrame.from_records(getattr(self, table))


def _path(path: Optional[StrPath]) -> Optional[str]:
    return None if path is None else os.fspath(path)


def study(
    scenes: Union[StrPath, Sequence[StrPath]],
    out: StrPath = "study",
    *,
    integrators: Optional[Union[str, Sequence[str]]] = None,
    budgets: Optional[Union[str, Sequence[int]]] = None,
    target_budget: Optional[int] = None,
    runs: Optional[int] = None,
    max_runs: Optional[int] = None,
    precision: Optional[float] = None,
    reference: Optional[StrPath] = None,
    reference_samples: Optional[int] = None,
    cache_dir: Optional[StrPath] = None,
    paper_pilots: bool = False,
    sweeps: Optional[Union[str, Sequence[str]]] = None,
    sweep_budget: Optional[int] = None,
    block: Optional[int] = None,
    epsilon: Optional[float] = None,
    overrides: Optional[Union[Mapping[str, Any], Sequence[str]]] = None,
    threads: Optional[int] = None,
    seed: Optional[int] = None,
    report: Optional[StrPath] = None,
    notes: Optional[StrPath] = None,
    progress: Optional[Callable[[int, int, str], Any]] = None,
) -> Study:
    """Measures the speed/accuracy trade of integrators on scenes, as ``lumis study`` does.

    The arguments are the CLI's options (``lumis study --help``, docs/study.md) in snake_case,
    with the CLI's defaults when None: integrators as ``["balance", "alpha:mode=preprocessed"]``
    or ``"balance,alpha"``, budgets as ``[4, 8, 16]``, sweeps as ``["clamp", "m"]``,
    overrides as for `lumis.load` (``{"film.width": 64}``). The study writes the CLI's files
    into `out` and returns their tables as values. progress(done, total, message) is called as
    the study advances (in samples per light per pixel). Ctrl-C stops the study at the next
    camera sample and raises KeyboardInterrupt (the finished scenes' files are written).
    Raises ValueError for options the CLI would refuse, SceneError for a broken scene and
    LumisError for anything else.
    """
    if isinstance(scenes, (str, os.PathLike)):
        scenes = [scenes]
    tables = _study(
        [os.fspath(s) for s in scenes],
        os.fspath(out),
        integrators=integrators,
        budgets=budgets,
        target_budget=target_budget,
        runs=runs,
        max_runs=max_runs,
        precision=precision,
        reference=_path(reference),
        reference_samples=reference_samples,
        cache_dir=_path(cache_dir),
        paper_pilots=paper_pilots,
        sweeps=sweeps,
        sweep_budget=sweep_budget,
        block=block,
        epsilon=epsilon,
        overrides=overrides,
        threads=threads,
        seed=seed,
        report=_path(report),
        notes=_path(notes),
        progress=progress,
    )
    return Study(
        results=tables["results"],
        trade=tables["trade"],
        curves=tables["curves"],
        out=Path(tables["out"]),
        report=Path(tables["report"]),
    )
