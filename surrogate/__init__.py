"""cbv-surrogate: counterbalance-valve models from CFD maps and bench data.

Data flow one way: files -> validated tables in SI (:mod:`surrogate.data`) -> maps -> valve model
-> solver -> comparison with measurements -> reports and the command line (:mod:`surrogate.cli`).
"""

from .fluid import FluidState, Oil
from .valve import ValveParameters, load_valve

__version__ = "0.1.0"
__all__ = ["FluidState", "Oil", "ValveParameters", "load_valve", "__version__"]
