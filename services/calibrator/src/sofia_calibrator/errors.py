"""Errors of the calibrator. Each constructor builds a message saying what was wrong, with the value."""

from __future__ import annotations

from sofia_schemas.errors import SofiaError


class CalibrationError(SofiaError, ValueError):
    """Base class of every calibrator error."""


class TooFewSamples(CalibrationError):  # noqa: N818 - named as in STYLE.md
    def __init__(self, n: int, need: int = 3) -> None:
        super().__init__(
            f"{n} calibration sample(s) given, at least {need} are needed "
            "(record the blob from more flange poses, tilted about different axes)"
        )
        self.n = n


class DegenerateMotion(CalibrationError):  # noqa: N818 - named as in STYLE.md
    def __init__(self, what: str, advice: str) -> None:
        super().__init__(f"{what}: {advice}")


class InputMismatch(CalibrationError):  # noqa: N818 - named as in STYLE.md
    def __init__(self, what: str) -> None:
        super().__init__(what)


class ParseError(CalibrationError):
    def __init__(self, path: object, line: int | None, what: str) -> None:
        where = f"{path}:{line}" if line is not None else f"{path}"
        super().__init__(f"{where}: {what}")


class BlobNotFound(CalibrationError):  # noqa: N818 - named as in STYLE.md
    def __init__(self, reason: str) -> None:
        super().__init__(f"no blob found: {reason}")


class BlobCutByEdge(CalibrationError):  # noqa: N818 - named as in STYLE.md
    def __init__(self, bbox: tuple[int, int, int, int], shape: tuple[int, int]) -> None:
        super().__init__(
            f"blob touches the image edge (rows {bbox[0]}-{bbox[1]}, cols {bbox[2]}-{bbox[3]} in a "
            f"{shape[0]}x{shape[1]} image): move the camera so the whole blob is in view"
        )


class BlobAmbiguous(CalibrationError):  # noqa: N818 - named as in STYLE.md
    def __init__(self, sizes: list[int]) -> None:
        super().__init__(
            f"{len(sizes)} dark blobs of similar size ({sizes} pixels): keep only one blob in view"
        )


class BlobNoDepth(CalibrationError):  # noqa: N818 - named as in STYLE.md
    def __init__(self, n_pixels: int, n_valid: int) -> None:
        super().__init__(f"blob has {n_pixels} pixels but only {n_valid} with valid depth")
