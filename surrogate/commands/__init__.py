"""The subcommands of ``python -m surrogate``, one module each."""

from . import check_data, compare, diagnose, fit, paper, predict, simulate, workflow

COMMANDS = (check_data, paper, predict, compare, diagnose, fit, workflow, simulate)
