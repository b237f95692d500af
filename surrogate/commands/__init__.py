"""The subcommands of ``python -m surrogate``, one module each."""

from . import check_data

COMMANDS = (check_data,)
