"""Every threshold of the judgement is defined once: no module that judges or words a finding
types one of the rule's values again where it compares or scales (``1.3 * floor`` beside
``NOISE_LEVEL = 1.3``), so that changing the rule changes every place it acts."""

from __future__ import annotations

import ast
from pathlib import Path

import surrogate
from surrogate.diagnosis import lookalikes, rule
from surrogate.reporting import prose

PACKAGE = Path(surrogate.__file__).parent

#: the values a retyped literal would repeat, with the constant that defines each (not the
#: bootstrap's majority, 0.5: every midpoint is one)
THRESHOLDS = {rule.BIC_THRESHOLD: "rule.BIC_THRESHOLD", -rule.BIC_THRESHOLD: "rule.BIC_THRESHOLD",
              rule.NOISE_MARGIN: "rule.NOISE_MARGIN", rule.GAIN_FRACTION: "rule.GAIN_FRACTION",
              rule.HELDOUT_GAIN: "rule.HELDOUT_GAIN", prose.NOISE_LEVEL: "prose.NOISE_LEVEL",
              lookalikes.COLLINEAR: "lookalikes.COLLINEAR",
              lookalikes.SAME_DIRECTION: "lookalikes.SAME_DIRECTION"}

#: the modules that judge a candidate, a step or a log, or put the judgement into words
JUDGING = [*sorted((PACKAGE / "diagnosis").glob("*.py")),
           *(PACKAGE / name for name in ("reporting/prose.py", "reporting/verdict.py",
                                         "reporting/kinds.py", "reporting/staircase.py",
                                         "reporting/naming.py",
                                         "workbench/workflow.py", "fitting/heldout.py"))]


def retyped_thresholds(source: str) -> list[tuple[int, float, str]]:
    """(line, value, constant) of each number in ``source`` that equals a threshold and stands
    in a comparison or an arithmetic operation (a figure's size or a count is neither)."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, (ast.Compare, ast.BinOp)):
            continue
        operands = ([node.left, *node.comparators] if isinstance(node, ast.Compare)
                    else [node.left, node.right])
        for operand in operands:
            if isinstance(operand, ast.UnaryOp) and isinstance(operand.op, ast.USub):
                operand, sign = operand.operand, -1.0
            else:
                sign = 1.0
            if (isinstance(operand, ast.Constant) and isinstance(operand.value, (int, float))
                    and not isinstance(operand.value, bool)):
                value = sign * float(operand.value)
                found += [(operand.lineno, value, name) for threshold, name in THRESHOLDS.items()
                          if value == threshold]
    return found


def test_the_check_sees_a_retyped_threshold():
    assert retyped_thresholds("quiet = rms <= 1.3 * floor") == [(1, 1.3, "prose.NOISE_LEVEL")]
    assert retyped_thresholds("strong = delta < -10") == [(1, -10.0, "rule.BIC_THRESHOLD")]
    assert retyped_thresholds("figure = Figure(figsize=(10, 5.2))") == []


def test_no_module_that_judges_retypes_a_threshold():
    retyped = [f"{path.relative_to(PACKAGE)}:{line}: {value:g} is {name}"
               for path in JUDGING
               for line, value, name in retyped_thresholds(path.read_text(encoding="utf-8"))]
    assert retyped == []
