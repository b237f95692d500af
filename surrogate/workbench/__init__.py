"""The measurement workbench: compare a model with bench data and close the loop (the
workflow): the rooms it draws on are :mod:`surrogate.fitting`, :mod:`surrogate.diagnosis`,
:mod:`surrogate.synthetic`, :mod:`surrogate.planning` and :mod:`surrogate.reporting`."""
