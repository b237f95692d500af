"""What the package writes as code carries no code from its inputs.

An effects file handed over by a diagnosis (:mod:`surrogate.effects.handover`) quotes where it
was found (the bench log's path) in its docstring, and users load it. A path, a run id or a
column name holding a quote and a call must stay text: the file runs nothing but what the
package wrote, and every file it writes passes :func:`checked_source` first.
"""

from __future__ import annotations

import os
import unicodedata
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from surrogate.effects import load_effects_file
from surrogate.effects.handover import checked_source, effect_source, write_effect_file
from surrogate.effects.shapes import OpeningForce

#: names that end a docstring and call open(): the attack the issue measured, and its kin
HOSTILE = ['x"""+str(open("PWNED","w"))+""".csv',
           "x'''+str(open('PWNED','w'))+'''.csv",
           'x\\"""+str(open("PWNED","w"))+"""',
           'x"""\nopen("PWNED", "w")\n"""',
           'trailing backslash \\',
           'x\\N{',
           '\x1b[31mred\x1b[0m and a bell\x07 and \u202eoverride',
           '"""']


def opening_force() -> OpeningForce:
    effect = OpeningForce.on_knots(np.linspace(0.02e-3, 0.6e-3, 6))
    for index, name in enumerate(effect.coefficient_names()):
        effect.params[name].value = 1.0 + index
    return effect


def load_in(folder: Path, source: str):
    """Load ``source`` as an effects file from ``folder`` (the working folder while it runs)."""
    path = folder / "found_force_of_opening.py"
    path.write_text(source)
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        (found,) = load_effects_file(path).values()
    finally:
        os.chdir(cwd)
    return found


@pytest.mark.parametrize("name", HOSTILE)
def test_a_hostile_origin_is_text_in_the_file_and_runs_nothing(name, tmp_path):
    source = effect_source(opening_force(), origin=name, note=name)
    found = load_in(tmp_path, source)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["found_force_of_opening.py"]
    # the name as text: control characters as their escapes, the docstring's line breaks aside
    shown = "".join(c if unicodedata.category(c)[0] != "C"
                    else c.encode("unicode_escape").decode("ascii") for c in name)
    assert " ".join(shown.split()) in " ".join(found.__doc__.split())


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(origin=st.text(max_size=60), note=st.text(max_size=60))
def test_any_text_as_origin_or_note_gives_a_file_that_passes_the_check(origin, note):
    checked_source(effect_source(opening_force(), origin=origin, note=note))


def test_the_file_name_is_a_name_or_nothing(tmp_path):
    """A file stem that is no Python name (or a keyword) is not used as the function's name."""
    for stem in ("class", "x-y", "a b"):
        path = write_effect_file(opening_force(), tmp_path / f"{stem}.py")
        assert "def found_force_of_opening(" in path.read_text()
    with pytest.raises(ValueError, match="not a Python name"):
        effect_source(opening_force(), name="open('x')")


GOOD = effect_source(opening_force(), origin="a log")


@pytest.mark.parametrize("edit", [
    lambda s: s.replace("import numpy as np", "import os\nimport numpy as np"),
    lambda s: s.replace("#: a fit adds", "open('PWNED', 'w')\n#: a fit adds"),
    lambda s: s.replace("ROUGHNESS = ", "ROUGHNESS = open('PWNED', 'w') or "),
    lambda s: s.replace("    return ", "    import os\n    return "),
    lambda s: s.replace("    return ", "    return np.__class__ and "),
    lambda s: s.replace("    return ", "    return [x for x in X] and "),
    lambda s: s + "\n\ndef another(state):\n    return 0\n",
    lambda s: s.replace("from surrogate.effects import custom_effect",
                        "from surrogate.effects import custom_effect\nfrom os import system"),
], ids=["import", "call-statement", "call-in-constant", "import-in-function", "dunder",
        "comprehension", "second-function", "from-import"])
def test_the_check_refuses_anything_but_the_expected_form(edit):
    """The control: the check is what stands between a name and the user's machine."""
    checked_source(GOOD)
    with pytest.raises(ValueError, match="effects file"):
        checked_source(edit(GOOD))
