"""A short, human summary of a loaded file, in display units (for ``check-data``)."""

from __future__ import annotations

import numpy as np

from ..core.units import from_si
from .loaders import BenchLog, CfdSamples


def summarize(table: CfdSamples | BenchLog) -> dict:
    """The summary as plain data in display units (bar, mm, L/min, °C, cSt)."""
    if isinstance(table, CfdSamples):
        return _summarize_cfd(table)
    return _summarize_bench(table)


def _range(values, unit: str) -> list[float]:
    converted = from_si(np.asarray(values), unit)
    return [round(float(converted.min()), 4), round(float(converted.max()), 4)]


def _levels(values, unit: str) -> list[float]:
    return sorted({round(float(v), 4) for v in from_si(np.asarray(values), unit)})


def _summarize_cfd(samples: CfdSamples) -> dict:
    frame = samples.frame
    by_temperature = []
    for temperature, group in frame.groupby("temperature"):
        by_temperature.append({
            "temperature_C": round(float(from_si(temperature, "degC")), 3),
            "rows": len(group),
            "nu_cSt": _levels(group["nu"], "cSt"),
            "rho_kg_m3": sorted({round(float(r), 3) for r in group["rho"]}),
        })
    return {
        "file": samples.source,
        "kind": "cfd_samples",
        "rows": len(frame),
        "oils": sorted(set(frame["oil"])),
        "temperatures": by_temperature,
        "u_mm": _levels(frame["u"], "mm"),
        "q_lpm_range": _range(frame["q"], "L/min"),
        "p_B_bar": _levels(frame["p_B"], "bar"),
        "p_L_bar_range": _range(frame["p_L"], "bar"),
        "f_sim_N_range": _range(frame["f_sim"], "N"),
    }


def _summarize_bench(log: BenchLog) -> dict:
    runs = []
    for run in log.runs():
        frame = run.frame
        runs.append({
            "run": run.run,
            "samples": len(run),
            "temperature_C_mean": round(float(from_si(run.temperature, "degC")), 2),
            "temperature_C_range": _range(frame["temperature"], "degC"),
            "p_Pe_nominal_bar": round(float(from_si(run.p_Pe_nominal, "bar")), 3),
            "q_lpm_range": _range(frame["q"], "L/min"),
            "p_L_bar_range": _range(frame["p_L"], "bar"),
            "p_B_bar_range": _range(frame["p_B"], "bar"),
            "time_s_range": _range(frame["time"], "s"),
            "up_samples": int((frame["direction"] == "up").sum()),
            "down_samples": int((frame["direction"] == "down").sum()),
        })
    return {"file": log.source, "kind": "bench_log", "rows": len(log), "runs": runs,
            "notes": list(log.notes)}


def format_summary(summary: dict) -> str:
    """The summary as text for a terminal."""
    if summary["kind"] == "cfd_samples":
        return _format_cfd(summary)
    return _format_bench(summary)


def _join(values) -> str:
    return ", ".join(f"{v:g}" for v in values)


def _format_cfd(s: dict) -> str:
    lines = [f"{s['file']}: CFD samples, {s['rows']} rows, oil {', '.join(s['oils'])}"]
    for t in s["temperatures"]:
        lines.append(f"  {t['temperature_C']:>6g} °C: {t['rows']:>3} rows, "
                     f"ν = {_join(t['nu_cSt'])} cSt, ρ = {_join(t['rho_kg_m3'])} kg/m³")
    lines += [
        f"  u levels      {_join(s['u_mm'])} mm",
        f"  q range       {s['q_lpm_range'][0]:g} to {s['q_lpm_range'][1]:g} L/min",
        f"  p_B levels    {_join(s['p_B_bar'])} bar",
        f"  p_L range     {s['p_L_bar_range'][0]:g} to {s['p_L_bar_range'][1]:g} bar",
        f"  f_sim range   {s['f_sim_N_range'][0]:g} to {s['f_sim_N_range'][1]:g} N",
    ]
    return "\n".join(lines)


def _format_bench(s: dict) -> str:
    lines = [f"{s['file']}: bench log, {s['rows']} rows, {len(s['runs'])} runs",
             f"  {'run':<6}{'samples':>8}{'T [°C]':>9}{'p_Pe set':>10}"
             f"{'q [L/min]':>15}{'p_L [bar]':>17}{'p_B [bar]':>13}{'up/down':>10}"]
    for r in s["runs"]:
        lines.append(
            f"  {r['run']:<6}{r['samples']:>8}{r['temperature_C_mean']:>9.1f}"
            f"{r['p_Pe_nominal_bar']:>7g} bar"
            f"{r['q_lpm_range'][0]:>8.2f}–{r['q_lpm_range'][1]:<6.2f}"
            f"{r['p_L_bar_range'][0]:>9.1f}–{r['p_L_bar_range'][1]:<7.1f}"
            f"{r['p_B_bar_range'][0]:>6.2f}–{r['p_B_bar_range'][1]:<6.2f}"
            f"{r['up_samples']:>5}/{r['down_samples']}")
    return "\n".join(lines)
