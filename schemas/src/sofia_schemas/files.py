"""Configuration files (boards, transforms, gripper configs): JSON when the name ends in ``.json``,
else YAML."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from .errors import SofiaError


class FileContentError(SofiaError, ValueError):
    """A file's text is not valid for its format; ``what`` says why."""

    def __init__(self, path: str | Path, what: str) -> None:
        self.path, self.what = Path(path), what
        super().__init__(f"{path}: {what}")


def load_json_or_yaml(path: str | Path) -> Any:
    """The parsed content of ``path`` (OSError when it cannot be read, FileContentError when it does
    not parse)."""
    path = Path(path)
    text = path.read_text()
    is_json = path.suffix.lower() == ".json"
    try:
        return json.loads(text) if is_json else yaml.safe_load(text)
    except (ValueError, yaml.YAMLError) as e:
        raise FileContentError(path, f"is not valid {'JSON' if is_json else 'YAML'}: {e}") from None
