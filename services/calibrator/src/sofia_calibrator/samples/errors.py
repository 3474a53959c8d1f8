"""Errors of the calibrator's sample store and queries; each constructor builds the message."""

from __future__ import annotations

from pathlib import Path

from ..errors import CalibrationError


class SampleLogError(CalibrationError):
    """The sample log cannot be opened, read or written."""

    def __init__(self, path: Path, what: str) -> None:
        super().__init__(f"{path}: {what}")
        self.path = path


class ImplausibleSample(CalibrationError):  # noqa: N818 - named as in STYLE.md
    def __init__(self, sample_id: int | None, reasons: list[str]) -> None:
        who = "new sample" if sample_id is None else f"sample {sample_id}"
        super().__init__(f"{who} refused: {'; '.join(reasons)}")
        self.reasons = reasons


class UnknownSamples(CalibrationError):  # noqa: N818 - named as in STYLE.md
    def __init__(self, missing: list[int], known: list[int]) -> None:
        shown = known if len(known) <= 20 else [*known[:20], f"... {len(known) - 20} more"]
        super().__init__(f"no sample with id {', '.join(map(str, missing))}: nothing removed (ids: {shown})")
        self.missing = missing


class CalibratorBusy(CalibrationError):  # noqa: N818 - named as in STYLE.md
    def __init__(self, waiting: int) -> None:
        super().__init__(f"busy, retry: {waiting} queries are already waiting for the calibrator")


class SaveFailed(CalibrationError):  # noqa: N818 - named as in STYLE.md
    def __init__(self, path: object, reason: str) -> None:
        super().__init__(f"save failed writing {path}: {reason} (that file keeps its previous content)")


MAX_SAMPLES = 2000  # default bound: a solve of 2,000 samples takes about a second; a lab run uses ~100


class TooManySamples(CalibrationError):  # noqa: N818 - named as in STYLE.md
    def __init__(self, limit: int) -> None:
        super().__init__(f"sample refused: the store holds its maximum of {limit} samples "
                         "(remove some, or reset; --max-samples sets the maximum)")  # fmt: skip
        self.limit = limit


class SolveFailed(CalibrationError):  # noqa: N818 - named as in STYLE.md
    def __init__(self, n: int, reason: str) -> None:
        super().__init__(f"solve with {n} samples failed: {reason}")


class CalibratorLate(CalibrationError):  # noqa: N818 - named as in STYLE.md
    def __init__(self, waited_s: float, deadline_s: float) -> None:
        super().__init__(f"busy, retry: the calibrator reached this query after {waited_s:.1f} s "
                         f"(its deadline is {deadline_s:g} s)")  # fmt: skip
