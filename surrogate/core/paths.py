"""Where the project's shipped files live.

The package is installed editable from the repository (see README), so the shipped data are found
next to it. Commands take explicit paths too; these are only their defaults.
"""

from pathlib import Path

PROJECT_ROOT = Path(__file__).resolve().parents[2]
SHIPPED_CFD_SAMPLES = PROJECT_ROOT / "cfd_samples" / "cfd_samples.csv"
SHIPPED_BENCH_LOG = PROJECT_ROOT / "measurements" / "bench_measurements.csv"
#: the committed trained surrogates, one folder per learned map kind (inside the package)
SHIPPED_SURROGATES = Path(__file__).resolve().parents[1] / "trained"


def shipped(path: Path) -> Path:
    """``path`` if it exists, else a clear error saying how to point at the file instead."""
    if not path.exists():
        raise FileNotFoundError(
            f"shipped file {path} not found: install the package from a clone of the repository "
            "with `pip install -e .`, or pass the file's path explicitly")
    return path
