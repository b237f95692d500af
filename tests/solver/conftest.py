"""The solver tests' shared setting: the CFDA model replayed over a few runs of the shipped log."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture(scope="session")
def cfda_on_runs(bench_log):
    """``make(count)``: (log, the CFDA model, its replay) on the first ``count`` of every fourth
    run of the shipped log."""
    from surrogate.description.modelfile import load_model
    from surrogate.fitting.residuals import replay_log

    def make(count: int):
        runs = bench_log.frame["run"].unique()[::4][:count]
        log = bench_log.take(np.flatnonzero(bench_log.frame["run"].isin(runs).to_numpy()))
        model = load_model("cfda")
        return log, model, replay_log(model, log, diagnostics=False)

    return make
