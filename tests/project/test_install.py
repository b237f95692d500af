"""The install path a new user takes: the README's two commands, the constraints file and CI.

CI must run exactly what the README tells a user to run, in an environment it builds itself, or a
missing install step can hide behind packages that happen to be on the CI machine.
"""

from __future__ import annotations

import re
import tomllib
from importlib import metadata

from surrogate.core.paths import PROJECT_ROOT

README = (PROJECT_ROOT / "README.md").read_text()
CI = (PROJECT_ROOT / ".ci" / "run").read_text()
CONSTRAINTS = (PROJECT_ROOT / "constraints.txt").read_text()


def quickstart_commands() -> list[str]:
    section = README.split("## Quickstart", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```bash\n(.+?)\n```", section, flags=re.S)


def pins() -> dict[str, str]:
    found = {}
    for line in CONSTRAINTS.splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            name, version = line.split("==")
            found[name.lower().replace("_", "-")] = version
    return found


def test_the_quickstart_is_two_commands_using_the_constraints():
    commands = quickstart_commands()
    assert len(commands) == 2
    for command in commands:
        assert "\n" not in command
        assert command.startswith("python -m pip install -c constraints.txt ")


def test_ci_runs_the_readmes_test_command_in_a_venv_it_makes():
    assert quickstart_commands()[1] in CI.splitlines()
    assert "python3 -m venv" in CI and "mktemp -d" in CI
    assert CI.index("venv/bin/activate") < CI.index(quickstart_commands()[1])


def test_every_dependency_is_pinned_and_torch_to_the_cpu_wheel():
    project = tomllib.loads((PROJECT_ROOT / "pyproject.toml").read_text())["project"]
    requirements = project["dependencies"] + project["optional-dependencies"]["test"]
    names = {re.split(r"[<>=!~ ;\[]", requirement, 1)[0].lower() for requirement in requirements}
    pinned = pins()
    assert names <= set(pinned), names - set(pinned)
    assert pinned["torch"] == "2.13.0"  # the version whose CPU wheel these machines hold


def test_this_environment_has_the_pinned_versions():
    """Run in CI's fresh venv, this proves the constraints were applied; elsewhere it says which
    installed package differs from the tested set."""
    different = {}
    for name, version in pins().items():
        try:
            installed = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue  # a dependency of a dependency on another platform
        if installed.split("+")[0] != version:
            different[name] = (installed, version)
    assert not different, f"installed (left) differs from constraints.txt (right): {different}"
