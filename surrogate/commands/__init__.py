"""The subcommands of ``python -m surrogate``, one module each."""

from . import check_data, paper

COMMANDS = (check_data, paper)
