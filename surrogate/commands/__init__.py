"""The subcommands of ``python -m surrogate``, one module each."""

from . import check_data, paper, predict

COMMANDS = (check_data, paper, predict)
