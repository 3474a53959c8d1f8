"""The import contracts of pyproject.toml (``lint-imports``): layers point down, no import cycles."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LINT_IMPORTS = str(Path(sys.executable).parent / "lint-imports")


def lint_imports(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([LINT_IMPORTS, *args], cwd=REPO, capture_output=True, text=True, timeout=300)


def test_contracts_are_kept() -> None:
    r = lint_imports("--no-cache")
    assert r.returncode == 0, r.stdout + r.stderr
    for name in ("Layers point down", "No import cycles", "Detector stages point down"):
        assert any(name in line and "KEPT" in line for line in r.stdout.splitlines()), r.stdout


def test_an_upward_import_breaks_the_layers(tmp_path: Path) -> None:
    """The checker sees real imports: the detector imports the schemas, so a layering that puts
    the schemas above the detector is broken."""
    config = tmp_path / "upside_down.ini"
    config.write_text(
        "[importlinter]\nroot_packages =\n    sofia_schemas\n    sofia_detector\n\n"
        "[importlinter:contract:upside-down]\nname = upside down\ntype = layers\n"
        "layers =\n    sofia_schemas\n    sofia_detector\n"
    )
    r = lint_imports("--no-cache", "--config", str(config))
    assert r.returncode == 1, r.stdout + r.stderr
    assert "upside down BROKEN" in r.stdout
    assert "sofia_detector" in r.stdout and "-> sofia_schemas" in r.stdout
