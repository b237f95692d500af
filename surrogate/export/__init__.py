"""Taking a fitted valve out of the workbench, into the simulators where machines are designed.

* :mod:`.valve_only`: the fitted model's valve physics, without the bench's sensor terms;
* :mod:`.characteristic`: the steady up and down branches of Δp(q), the curve a catalogue shows;
* :mod:`.tables`: the valve as lookup tables (the friction band's edges over the inputs and
  Δp over the opening) with the play between the edges, replayed in Python exactly as a table
  block or an FMU would, and written as CSV, MATLAB ``.mat`` and a JSON manifest.
"""
