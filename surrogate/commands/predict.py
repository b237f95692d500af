"""``predict``: evaluate a flow and a force map at the states of a query file."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from ..data.queries import load_queries
from ..maps.coverage import describe_all
from ..maps.registry import build_maps
from ..core.errors import InputError
from ..core.outputs import Output, atomic_directory, atomic_file
from ..core.units import from_si
from ..valve import load_valve
from .common import (add_command, guard_outputs, legacy_option, maps_help_text, maps_option,
                     notice, print_json, progress_for, required)


def register(subparsers) -> None:
    parser = add_command(
        subparsers, "predict", help="evaluate q_sim and f_sim maps at given states",
        description="Read states (u_mm, p_L_bar, p_B_bar and temperature_C, or nu_cSt and "
                    "rho_kg_m3 for another oil), evaluate the flow and force map, and write the "
                    "input with q_lpm_pred, q_lpm_std, f_sim_N_pred, f_sim_N_std (calibrated "
                    "standard deviations; empty for maps without data), extrapolating and "
                    "outside_samples (why a state lies outside the CFD samples).")
    options = required(parser)
    options.add_argument("--maps", required=True, type=maps_option, help=maps_help_text())
    options.add_argument("--data", help="query CSV (states to evaluate the maps at)")
    options.add_argument("--out", help="output folder: the predictions are written as "
                                       "FOLDER/predictions.csv")
    # the release before's spellings, taken for one more release with a note
    parser.add_argument("--input", help=argparse.SUPPRESS)
    parser.add_argument("--output", help=argparse.SUPPRESS)
    parser.add_argument("--valve", help="valve file (default: the shipped valve)")
    parser.add_argument("--cfd", help="CFD samples for grid maps (default: the shipped ones)")
    parser.set_defaults(func=run)


def run(args) -> int:
    legacy_option(args, "--input", "--data")
    if args.output is not None:
        if args.out is not None:
            raise InputError("--output and --out name the same thing: give --out only")
        notice("note: --output FILE is now --out FOLDER (the predictions are written as "
               "FOLDER/predictions.csv); --output is taken as before in this release")
        target, path = Output("--output", args.output, "file"), Path(args.output)
    elif args.out is not None:
        target, path = Output("--out", args.out, "folder"), Path(args.out) / "predictions.csv"
    else:
        raise InputError("predict needs --out FOLDER (where predictions.csv is written)")
    if args.data is None:
        raise InputError("predict needs --data FILE (the query CSV)")
    guard_outputs(args, target)
    queries = load_queries(args.data)
    valve = load_valve(args.valve)
    flow_map, force_map = build_maps(args.maps.spec(args.cfd), valve)
    fluid = queries.fluid(valve.oil)
    state = (queries.p_L, queries.p_B, queries.u, fluid)
    table = queries.raw.copy()
    q_std, f_std = flow_map.flow_std(*state), force_map.force_std(*state)
    table["q_lpm_pred"] = from_si(flow_map.flow(*state), "L/min")
    table["q_lpm_std"] = np.nan if q_std is None else from_si(q_std, "L/min")
    table["f_sim_N_pred"] = force_map.force(*state)
    table["f_sim_N_std"] = np.nan if f_std is None else f_std
    reasons = np.asarray(flow_map.extrapolation_reasons(*state)
                         | force_map.extrapolation_reasons(*state))
    table["extrapolating"] = reasons != 0
    table["outside_samples"] = describe_all(reasons)
    if target.kind == "folder":
        with atomic_directory(target.path) as staging:
            _write_whole(table, staging / path.name)
    else:
        _write_whole(table, path)
    extrapolating = int(table["extrapolating"].sum())
    if args.json:
        print_json({"output": str(path), "predictions": len(table),
                    "extrapolating": extrapolating, "maps": str(args.maps)})
    else:
        progress_for(args)(f"wrote {len(table)} predictions ({extrapolating} extrapolating) "
                           f"with {args.maps} maps to {path}")
    return 0


def _write_whole(frame, path: Path) -> None:
    """Write a CSV through a temporary file, so a failure leaves no half-written output."""
    with atomic_file(path) as stream:
        frame.to_csv(stream, index=False, float_format="%.10g")
