"""Compare: how much, and where, a model and a bench log disagree.

The model is replayed over every run of the log (:func:`~surrogate.fitting.residuals.replay_log`);
the residual of a
sample is the model's Δp = p_L − p_B minus the measured one. The comparison summarises it

* over the whole log: RMS and the noise floor no model can beat
  (:func:`~surrogate.fitting.residuals.noise_floor`);
* per run: RMS, bias, the error in hysteresis width and the worst samples;
* per pilot set point × temperature: RMS;
* per operating region (flow band × temperature × set point), ranked by RMS, with how much of it
  lies where the model extrapolates its maps;
* the maps' own uncertainty: the Δp standard deviation it implies (RMS per run and overall,
  :mod:`surrogate.solver.uncertainty`), and the share of samples outside the CFD samples per
  reason (:mod:`surrogate.maps.coverage`).

Statistics are computed in SI; the tables are for display and hold bar, L/min and °C (their
column names say which). Samples the solver could not solve (NaN residual) are left out of every
statistic and counted in the ``failed`` column.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..data.loaders import BenchLog
from ..fitting.residuals import LogReplay, noise_floor, replay_log, run_groups_of
from ..maps.coverage import describe_all, shares
from ..core.memory import release_freed
from ..model import ValveModel
from ..solver.steady import status_names
from ..core.texttable import cell, text_table
from ..core.units import from_si

FLOW_BANDS = 4  # equal-width bands over the log's flow range, for the operating regions
HYSTERESIS_BINS = 10  # flow bins within a run in which the ramps up and down are matched
WORST_PER_RUN = 3  # samples with the largest |residual| kept per run
TEXT_RUNS = 30  # runs listed in the text summary; a bigger log lists its worst
# Runs are grouped by temperature rounded to this step: a bench holds its oil to about a degree
# around set points that are tens of degrees apart, so rounding recovers the set point.
TEMPERATURE_STEP_C = 5.0


@dataclass(frozen=True)
class Comparison:
    """The result of :func:`compare`.

    Attributes
    ----------
    model : str
        The model's name.
    log_replay : LogReplay
        The model's replay of the log.
    rms : float
        Residual RMS over the solved samples [Pa].
    noise_floor : float
        The residual's white-noise level, the lowest RMS any model could reach [Pa].
    runs : pandas.DataFrame
        One row per run in file order: ``run``, ``temperature_C`` (mean),
        ``temperature_nominal_C`` (rounded to :data:`TEMPERATURE_STEP_C`), ``p_Pe_bar`` (set
        point), ``samples``, ``failed``, ``rms_bar``, ``bias_bar`` (mean residual), ``noise_bar``
        (the run's noise floor), ``hysteresis_measured_bar``, ``hysteresis_model_bar``,
        ``hysteresis_error_bar`` (model minus measured width, see :func:`hysteresis_width`),
        ``dp_std_bar`` (RMS over the run of the Δp standard deviation the maps' uncertainty
        implies; NaN for maps without one) and ``extrapolating_fraction``.
    pivot : pandas.DataFrame
        RMS [bar] with the set point ``p_Pe_bar`` as index and ``temperature_C`` (nominal) as
        columns.
    regions : pandas.DataFrame
        Operating regions ranked by RMS, worst first: ``q_low_lpm``, ``q_high_lpm``,
        ``temperature_C`` (nominal), ``p_Pe_bar``, ``samples``, ``rms_bar``, ``bias_bar``,
        ``extrapolating_fraction`` and ``extrapolating`` (True when any sample extrapolates).
    worst : pandas.DataFrame
        The :data:`WORST_PER_RUN` samples of largest |residual| in each run: ``run``, ``line``
        (in the file), ``time_s``, ``q_lpm``, ``direction``, ``dp_measured_bar``,
        ``dp_model_bar``, ``residual_bar``.
    """

    model: str
    log_replay: LogReplay = field(repr=False)
    rms: float
    noise_floor: float
    runs: pd.DataFrame = field(repr=False)
    pivot: pd.DataFrame = field(repr=False)
    regions: pd.DataFrame = field(repr=False)
    worst: pd.DataFrame = field(repr=False)

    @property
    def samples(self) -> int:
        return len(self.log_replay.residual)

    @property
    def solved(self) -> int:
        return int(self.log_replay.ok.sum())

    @property
    def rms_over_noise(self) -> float:
        """How many times the noise floor the RMS is: near 1, nothing is left to model."""
        return self.rms / self.noise_floor if self.noise_floor > 0 else float("nan")

    @property
    def extrapolating_fraction(self) -> float:
        """Fraction of the solved samples at which the model extrapolates its maps."""
        ok = self.log_replay.ok
        if not ok.any():
            return float("nan")
        return float(np.mean(self.log_replay.replay.extrapolating[ok]))

    @property
    def outside_shares(self) -> dict[str, float]:
        """Share of the solved samples outside the CFD samples, for any reason and per reason."""
        return shares(self.log_replay.replay.reasons_outside[self.log_replay.ok])

    @property
    def dp_std(self) -> float:
        """RMS over the solved samples of the Δp standard deviation the maps' uncertainty
        implies [Pa]; NaN for maps without one."""
        std = self.log_replay.replay.dp_std
        if std is None or not self.log_replay.ok.any():
            return float("nan")
        return float(np.sqrt(np.nanmean(std[self.log_replay.ok] ** 2)))

    def to_json(self) -> dict:
        """Plain JSON data in display units, numbers rounded to 4 decimals, NaN as null."""
        worst = {run: _records(group.drop(columns="run"))
                 for run, group in self.worst.groupby("run", sort=False)}
        runs = [{**row, "worst": worst.get(row["run"], [])} for row in _records(self.runs)]
        pivot = self.pivot.stack().rename("rms_bar").reset_index()
        return {
            "model": self.model,
            "source": self.log_replay.log.source,
            "samples": self.samples,
            "solved": self.solved,
            "rms_bar": _plain(from_si(self.rms, "bar")),
            "noise_floor_bar": _plain(from_si(self.noise_floor, "bar")),
            "rms_over_noise": _plain(self.rms_over_noise),
            "dp_std_bar": _plain(from_si(self.dp_std, "bar")),
            "extrapolating_fraction": _plain(self.extrapolating_fraction),
            "outside_samples": {key: _plain(value) for key, value in self.outside_shares.items()},
            "runs": runs,
            "rms_by_p_Pe_and_temperature": _records(pivot),
            "regions": _records(self.regions),
        }

    def format_text(self, regions: int = 5) -> str:
        """A plain-text summary for a terminal: headline, per-run table, pivot, worst regions."""
        rms, floor = from_si(self.rms, "bar"), from_si(self.noise_floor, "bar")
        lines = [
            f"{self.model} vs {Path(self.log_replay.log.source).name}: {self.samples} samples in "
            f"{len(self.runs)} runs" + (f", {self.samples - self.solved} not solved"
                                        if self.solved < self.samples else ""),
            f"  residual (model − measured Δp) RMS {rms:.3f} bar, noise floor {floor:.3f} bar "
            f"({self.rms_over_noise:.1f}x); {self._outside_words()}",
            self._uncertainty_line(),
            "",
        ]
        runs = self.runs
        if len(runs) > TEXT_RUNS:  # a big log: its worst runs; the file has them all
            runs = runs.sort_values("rms_bar", ascending=False, kind="stable").head(TEXT_RUNS)
            lines.append(f"  The {TEXT_RUNS} runs of largest RMS (of {len(self.runs)}; every run "
                         "is in runs.csv with --out):")
        not_measured = "not measured"  # a run without both ramps has no hysteresis width
        lines += text_table(
            ["run", "T [°C]", "p_Pe [bar]", "samples", "RMS", "bias", "noise", "maps σ",
             "hyst. data", "model", "error", "extrap."],
            [[str(r.run), cell(r.temperature_C, ".1f"), cell(r.p_Pe_bar, "g"), str(r.samples),
              cell(r.rms_bar, ".3f"), cell(r.bias_bar, "+.3f"), cell(r.noise_bar, ".3f"),
              cell(r.dp_std_bar, ".3f"), cell(r.hysteresis_measured_bar, ".3f", not_measured),
              cell(r.hysteresis_model_bar, ".3f", not_measured),
              cell(r.hysteresis_error_bar, "+.3f", not_measured),
              cell(100 * r.extrapolating_fraction, ".0f") + "%"]
             for r in runs.itertuples(index=False)])
        lines.append("  (in bar; maps σ: RMS of the Δp standard deviation the maps' uncertainty "
                     "implies; hysteresis width: Δp of the ramp up − ramp down at equal q, not "
                     "measured for a run without both ramps)")

        lines += ["", "  RMS [bar] by p_Pe set point (rows) and temperature (columns):"]
        lines += text_table(
            ["p_Pe", *(f"{t:g} °C" for t in self.pivot.columns)],
            [[f"{p_Pe:g} bar", *(cell(v, ".3f") for v in row)]
             for p_Pe, row in self.pivot.iterrows()], left=())

        lines += ["", f"  Worst operating regions (of {len(self.regions)}):"]
        for r in self.regions.head(regions).itertuples(index=False):
            flag = (f", maps extrapolated at {100 * r.extrapolating_fraction:.0f} %"
                    if r.extrapolating else "")
            lines.append(f"    q {r.q_low_lpm:.1f}–{r.q_high_lpm:.1f} L/min, "
                         f"{r.temperature_C:g} °C, p_Pe {r.p_Pe_bar:g} bar: RMS {r.rms_bar:.3f} "
                         f"bar, bias {r.bias_bar:+.3f} bar, {r.samples} samples{flag}")
        return "\n".join(lines)


    def sample_table(self, rows=slice(None)) -> pd.DataFrame:
        """One row per sample (or per sample of ``rows``, positions) in display units: inputs,
        measured and model Δp, the model's Δp standard deviation from the maps, residual,
        solver status, whether the piston moved, and why the maps' query lies outside the CFD
        samples (empty inside)."""
        log, log_replay, replay = self.log_replay.log.frame, self.log_replay, self.log_replay.replay
        dp_std = replay.dp_std

        def column(name):
            return log[name].to_numpy()[rows]

        return pd.DataFrame({
            "run": column("run"),
            "line": column("line"),
            "time_s": column("time"),
            "direction": column("direction"),
            "q_lpm": from_si(column("q"), "L/min"),
            "p_P_bar": from_si(column("p_P"), "bar"),
            "p_B_bar": from_si(column("p_B"), "bar"),
            "temperature_C": from_si(column("temperature"), "degC"),
            "dp_measured_bar": from_si(log_replay.measured[rows], "bar"),
            "dp_model_bar": from_si(replay.dp[rows], "bar"),
            "dp_std_bar": from_si(np.full(len(log_replay.residual), np.nan)[rows] if dp_std is None
                                  else dp_std[rows], "bar"),
            "residual_bar": from_si(log_replay.residual[rows], "bar"),
            "status": status_names(replay.status[rows]),
            "moving": replay.moving[rows],
            "outside_samples": describe_all(replay.reasons_outside[rows]),
        })

    def write_samples(self, path, chunk: int = 200_000) -> None:
        """Write :meth:`sample_table` as CSV, a chunk of rows at a time (the table of a big log
        is never held whole)."""
        count = len(self.log_replay.residual)
        with open(path, "w", encoding="utf-8", newline="") as stream:
            for start in range(0, max(count, 1), chunk):
                self.sample_table(slice(start, min(start + chunk, count))).to_csv(
                    stream, index=False, header=start == 0, float_format="%.6g")

    def _outside_words(self) -> str:
        """Where the maps are read outside their CFD samples, said with the main reason: the
        bench's back pressure alone lies outside a CFD that ran at one, which is not the same as
        openings or oils the CFD never saw."""
        share = self.extrapolating_fraction
        if not share:
            return "maps read within their CFD samples throughout"
        reasons = {reason: value for reason, value in self.outside_shares.items()
                   if reason != "any" and value > 0}
        words = f"maps read outside their CFD samples at {100 * share:.0f} % of samples"
        if not reasons:
            return words
        main = max(reasons, key=reasons.get)
        return words + f", most by the {main.replace(' outside the sampled ones', '')} " \
                       f"({100 * reasons[main]:.0f} %; below)"

    def _uncertainty_line(self) -> str:
        """The maps' Δp standard deviation and why samples lie outside the CFD samples."""
        std = from_si(self.dp_std, "bar")
        head = ("  maps' uncertainty: none (maps without data)" if not np.isfinite(std) else
                f"  maps' uncertainty: Δp standard deviation {std:.3f} bar RMS")
        reasons = [f"{100 * share:.0f} % {reason}" for reason, share in
                   self.outside_shares.items() if reason != "any" and share > 0]
        return head + ("; outside the CFD samples: " + ", ".join(reasons) if reasons else "")


def compare(model: ValveModel, log: BenchLog, *, log_replay: LogReplay | None = None,
            progress=None) -> Comparison:
    """Replay ``model`` over ``log`` and summarise the residual (see the module doc).

    ``log_replay``: the model's replay of ``log``, if already computed. It must have been made with
    diagnostics on (the default of :func:`~surrogate.fitting.residuals.replay_log`), or every
    region reads as inside the maps
    and no uncertainty is shown. ``progress`` hears how far the replay of a big log got.
    """
    log_replay = log_replay if log_replay is not None else replay_log(model, log, progress=progress)
    if len(log_replay.residual) != len(log):
        raise ValueError(f"the replay has {len(log_replay.residual)} samples, the log {len(log)}")
    log_replay.require_solved(model.name)
    samples = _samples(log_replay)
    solved_rows = samples["residual"].notna().to_numpy()
    solved = samples if solved_rows.all() else samples[solved_rows]  # no copy when all solve
    comparison = Comparison(
        model=model.name,
        log_replay=log_replay,
        rms=log_replay.rms(),
        noise_floor=noise_floor(log_replay.residual, log_replay.runs, source=log_replay.log.source),
        runs=_run_table(samples, solved, log.run_ids),
        pivot=_pivot(solved),
        regions=_regions(solved, samples["q"]),
        worst=_worst(solved, log.run_ids, log.frame),
    )
    release_freed(len(log))
    return comparison


def hysteresis_width(runs, q, direction, dp, bins: int = HYSTERESIS_BINS) -> pd.Series:
    """Hysteresis width of each run: Δp on the ramp up minus Δp on the ramp down at equal flow.

    The run's flow range is cut into ``bins`` equal bins; in each bin holding both directions the
    mean Δp of the "down" samples is subtracted from that of the "up" samples, and the width is
    the mean of these gaps over the bins. Matching by flow bins, not by time, keeps the width
    independent of how fast each ramp was driven.

    Parameters
    ----------
    runs, q, direction, dp : array_like
        Run label, flow [m^3/s], ramp direction (``"up"``/``"down"``, or True for up) and Δp
        [Pa] per sample; samples with NaN Δp are ignored.

    Returns
    -------
    pandas.Series
        Width [Pa] by run (NaN for a run without both directions in any bin).
    """
    codes, names = pd.factorize(np.asarray(runs), sort=False)  # small integers, not labels
    direction, dp, q = np.asarray(direction), np.asarray(dp, float), np.asarray(q, float)
    up = direction if direction.dtype == bool else direction == "up"
    widths = np.full(len(names), np.nan)
    # a block of runs at a time: the groupings below take a few hundred bytes per sample
    for first in range(0, len(names), HYSTERESIS_RUNS_PER_BLOCK):
        block = ((codes >= first) & (codes < first + HYSTERESIS_RUNS_PER_BLOCK)
                 if len(names) > HYSTERESIS_RUNS_PER_BLOCK else slice(None))
        width = _widths(codes[block] - first, q[block], up[block], dp[block], bins)
        widths[first + width.index.to_numpy()] = width.to_numpy()
    return pd.Series(widths, index=pd.Index(names, name="run"))


#: runs whose hysteresis widths are computed together (a log of up to this many runs in one go)
HYSTERESIS_RUNS_PER_BLOCK = 256


def _widths(codes: np.ndarray, q: np.ndarray, up: np.ndarray, dp: np.ndarray,
            bins: int) -> pd.Series:
    """:func:`hysteresis_width` of runs numbered 0, 1, ... (``codes``), by number."""
    frame = pd.DataFrame({"run": codes, "q": q, "up": up, "dp": dp})
    frame = frame[np.isfinite(frame["dp"])]
    flow = frame.groupby("run", sort=False)["q"]
    low, high = flow.transform("min"), flow.transform("max")
    span = (high - low).where(high > low, 1.0)  # a run at one flow is one bin
    frame = frame.assign(bin=np.clip(np.floor((frame["q"] - low) / span * bins), 0, bins - 1))
    means = (frame.groupby(["run", "bin", "up"], sort=False)["dp"].mean()
             .unstack("up").reindex(columns=[True, False]))
    gap = (means[True] - means[False]).dropna()
    return gap.groupby(level="run", sort=False).mean()


def _samples(log_replay: LogReplay) -> pd.DataFrame:
    """What the statistics need of each sample (SI): the log's run, flow, ramp direction (up
    as True), temperature and set point, the measured and predicted Δp, the residual and its
    square, the Δp variance the maps imply, whether they extrapolate, and the run's nominal
    temperature. Only these: a log of millions of samples is not copied whole."""
    log, replay = log_replay.log.frame, log_replay.replay
    std = np.full(len(log_replay.residual), np.nan) if replay.dp_std is None else replay.dp_std
    samples = pd.DataFrame({name: log[name].to_numpy() for name in (
        "run", "q", "temperature", "p_Pe_nominal")})
    samples["up"] = log["direction"].to_numpy() == "up"
    samples["dp_measured"] = log_replay.measured
    samples["dp_predicted"] = replay.dp
    samples["residual"] = log_replay.residual
    samples["extrapolating"] = replay.extrapolating
    samples["residual_squared"] = samples["residual"] ** 2
    samples["dp_variance"] = std ** 2
    run_temperature = samples.groupby("run", sort=False)["temperature"].transform("mean")
    samples["temperature_nominal_C"] = TEMPERATURE_STEP_C * np.round(
        from_si(run_temperature.to_numpy(), "degC") / TEMPERATURE_STEP_C)
    return samples


def _display(values: pd.Series, unit: str) -> pd.Series:
    """``values`` (SI) converted to ``unit``, keeping their index."""
    return pd.Series(from_si(values.to_numpy(dtype=float), unit), index=values.index)


def _run_table(samples: pd.DataFrame, solved: pd.DataFrame, run_ids: list[str]) -> pd.DataFrame:
    every, good = samples.groupby("run", sort=False), solved.groupby("run", sort=False)
    # both widths from the same (solved) samples, so that failures cannot fake a difference
    measured = hysteresis_width(samples["run"], samples["q"], samples["up"],
                                samples["dp_measured"].where(samples["residual"].notna()))
    predicted = hysteresis_width(samples["run"], samples["q"], samples["up"],
                                 samples["dp_predicted"])
    residual, runs = samples["residual"].to_numpy(), samples["run"].to_numpy()
    noise = pd.Series({runs[rows[0]]: noise_floor(residual[rows], runs[rows], required=False)
                       for rows in run_groups_of(runs)})
    table = pd.DataFrame({
        "temperature_C": _display(every["temperature"].mean(), "degC"),
        "temperature_nominal_C": every["temperature_nominal_C"].first(),
        "p_Pe_bar": _display(every["p_Pe_nominal"].first(), "bar"),
        "samples": every.size(),
        "failed": every.size() - good.size().reindex(run_ids, fill_value=0),
        "rms_bar": _display(np.sqrt(good["residual_squared"].mean()), "bar"),
        "bias_bar": _display(good["residual"].mean(), "bar"),
        "noise_bar": _display(noise, "bar"),
        "hysteresis_measured_bar": _display(measured, "bar"),
        "hysteresis_model_bar": _display(predicted, "bar"),
        "hysteresis_error_bar": _display(predicted - measured, "bar"),
        "dp_std_bar": _display(np.sqrt(good["dp_variance"].mean()), "bar"),
        "extrapolating_fraction": good["extrapolating"].mean().astype(float),
    }).reindex(run_ids)
    table.index.name = "run"
    return table.reset_index()


def _pivot(solved: pd.DataFrame) -> pd.DataFrame:
    mean_square = solved.groupby(["p_Pe_nominal", "temperature_nominal_C"])["residual_squared"]
    rms = np.sqrt(mean_square.mean()).unstack("temperature_nominal_C")
    pivot = pd.DataFrame(from_si(rms.to_numpy(), "bar"),
                         index=pd.Index(from_si(rms.index.to_numpy(), "bar"), name="p_Pe_bar"),
                         columns=pd.Index(rms.columns.to_numpy(), name="temperature_C"))
    return pivot


def _regions(solved: pd.DataFrame, q: pd.Series) -> pd.DataFrame:
    """Flow band × nominal temperature × set point, ranked by RMS (worst first)."""
    edges = np.linspace(q.min(), q.max(), FLOW_BANDS + 1)
    band = np.clip(np.searchsorted(edges, solved["q"], side="right") - 1, 0, FLOW_BANDS - 1)
    groups = solved.assign(band=band).groupby(["band", "temperature_nominal_C", "p_Pe_nominal"])
    stats = groups.agg(samples=("residual", "size"), mean_square=("residual_squared", "mean"),
                       bias=("residual", "mean"), extrapolating_fraction=("extrapolating", "mean"))
    stats = stats.reset_index()
    regions = pd.DataFrame({
        "q_low_lpm": from_si(edges[stats["band"].to_numpy()], "L/min"),
        "q_high_lpm": from_si(edges[stats["band"].to_numpy() + 1], "L/min"),
        "temperature_C": stats["temperature_nominal_C"],
        "p_Pe_bar": from_si(stats["p_Pe_nominal"].to_numpy(), "bar"),
        "samples": stats["samples"],
        "rms_bar": from_si(np.sqrt(stats["mean_square"].to_numpy()), "bar"),
        "bias_bar": from_si(stats["bias"].to_numpy(), "bar"),
        "extrapolating_fraction": stats["extrapolating_fraction"].astype(float),
        "extrapolating": stats["extrapolating_fraction"].to_numpy() > 0,
    })
    return regions.sort_values("rms_bar", ascending=False, kind="stable").reset_index(drop=True)


def _worst(solved: pd.DataFrame, run_ids: list[str], log: pd.DataFrame) -> pd.DataFrame:
    """The :data:`WORST_PER_RUN` samples of largest |residual| per run (their time and line
    from ``log``, the log's frame, whose rows ``solved`` keeps as its index)."""
    order = {run: index for index, run in enumerate(run_ids)}
    # ranked on the two columns that decide, then the few rows kept taken whole
    ranked = pd.DataFrame({"run": solved["run"], "size": solved["residual"].abs()}).sort_values(
        "size", ascending=False)
    kept = ranked.groupby("run", sort=False).head(WORST_PER_RUN)
    worst = solved.loc[kept.index].assign(size=kept["size"])
    worst = worst.assign(order=worst["run"].map(order)).sort_values(
        ["order", "size"], ascending=[True, False], kind="stable")
    return pd.DataFrame({
        "run": worst["run"].to_numpy(),
        "line": log["line"].to_numpy()[worst.index.to_numpy()],
        "time_s": log["time"].to_numpy()[worst.index.to_numpy()],
        "q_lpm": from_si(worst["q"].to_numpy(), "L/min"),
        "direction": log["direction"].to_numpy()[worst.index.to_numpy()],
        "dp_measured_bar": from_si(worst["dp_measured"].to_numpy(), "bar"),
        "dp_model_bar": from_si(worst["dp_predicted"].to_numpy(), "bar"),
        "residual_bar": from_si(worst["residual"].to_numpy(), "bar"),
    })


def _plain(value):
    """A JSON-ready scalar: Python bool/int/str, floats rounded to 4 decimals, NaN as None."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return round(float(value), 4) if np.isfinite(value) else None
    return value


def _records(table: pd.DataFrame) -> list[dict]:
    return [{str(key): _plain(value) for key, value in row.items()}
            for row in table.to_dict("records")]
