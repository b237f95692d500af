"""Many valves: one model fitted (and optionally diagnosed) on every bench log of a batch, on this
machine or on a Dask cluster, with the population's statistics and the valves that stand out.

The pieces, one module each:

* :mod:`.tasks`: which logs a batch holds (one per valve, the serial its file's stem) and what
  one valve's work is (:class:`~.tasks.ValveTask`: the log, the model as text, their hashes);
* :mod:`.valve`: that work, for one valve: read its log, fit, held-out RMS, noise floor,
  optionally the diagnosis; the result as plain JSON data;
* :mod:`.runner`: running the tasks on a local process pool or a Dask cluster, each result
  handed back as it completes;
* :mod:`.results`: the per-valve result files (written as they complete, so that a rerun skips
  the finished valves) and the fleet's tables;
* :mod:`.population`: median, robust spread, correlations, and the outliers by robust distance,
  with the parameter that makes each stand out;
* :mod:`.report`: the fleet's HTML report.

The command line is :mod:`surrogate.commands.fleet`; ``docs/fleet.md`` is the manual.
"""
