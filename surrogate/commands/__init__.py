"""The subcommands of ``python -m surrogate``, one module each."""

from . import (check_data, compare, diagnose, effects, export, fit, fleet, paper, predict,
               simulate, steady, suggest_cfd, workflow)

COMMANDS = (check_data, paper, predict, compare, diagnose, fit, workflow, fleet, suggest_cfd,
            simulate, steady, export, effects)
