"""The one place where gradgps defines its exceptions.

Every error a user can meet derives from :class:`GradGPSError`, so callers can
catch the library's own failures without catching programming errors. Errors
about input data carry *where* the problem is (file, row or line, column) so
the message alone is enough to fix the file.
"""

from __future__ import annotations

__all__ = [
    "ConfigError",
    "DataNotFoundError",
    "GradGPSError",
    "InputError",
    "InputWarning",
    "ModelError",
]


class GradGPSError(Exception):
    """Base class of every error raised on purpose by gradgps."""


class InputError(GradGPSError, ValueError):
    """Input data that cannot be used: a bad file, row, column or value.

    The message is built from the location fields so every reader reports
    problems the same way: ``FILE: row 57 (line 58), column 'lat': not a
    number: 'abc'. <hint>``.
    """

    def __init__(
        self,
        message: str,
        *,
        source: str | None = None,
        row: int | None = None,
        line: int | None = None,
        column: str | None = None,
        hint: str | None = None,
    ) -> None:
        self.reason = message
        self.source = source
        self.row = row
        self.line = line
        self.column = column
        self.hint = hint
        super().__init__(self._format())

    def _format(self) -> str:
        where: list[str] = []
        if self.row is not None:
            where.append(
                f"row {self.row}" + (f" (line {self.line})" if self.line is not None else "")
            )
        elif self.line is not None:
            where.append(f"line {self.line}")
        if self.column is not None:
            where.append(f"column {self.column!r}")
        text = ", ".join(where)
        if self.source:
            text = f"{self.source}: {text}" if text else self.source
        text = f"{text}: {self.reason}" if text else self.reason
        if self.hint:
            text = f"{text}. {self.hint}"
        return text


class ConfigError(GradGPSError, ValueError):
    """An invalid parameter or option (out of range, unknown name, wrong type)."""


class ModelError(GradGPSError):
    """A model directory that cannot be loaded: missing, truncated, tampered or of another version."""


class DataNotFoundError(GradGPSError, FileNotFoundError):
    """A named dataset or data folder that is not where it was looked for."""


class InputWarning(UserWarning):
    """Input outside what the model was validated on: answers there are not backed by
    a measurement (a slow rate, repeated timestamps, a noisy receiver, a reported speed
    in another unit...). Raised as a warning, once per problem and call, by
    :meth:`gradgps.Detector.detect`, :meth:`gradgps.Detector.clean`,
    :func:`gradgps.detect` and :func:`gradgps.clean`; the command line prints the same
    sentences as ``warning:`` lines. ``warnings.simplefilter("error", InputWarning)``
    turns them into errors, ``"ignore"`` silences them."""
