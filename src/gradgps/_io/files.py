"""Opening input files: existence checks, transparent gzip, line-exact UTF-8 decoding.

Shared by every reader so a missing file, a damaged ``.gz`` or a binary file
is reported the same way whatever the format.
"""

from __future__ import annotations

import gzip
import io
import zlib
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path

from .._exceptions import InputError

__all__ = [
    "MAX_LINE_BYTES",
    "READ_ERRORS",
    "check_readable",
    "damaged",
    "open_bytes",
    "text_lines",
]


#: Longest line a text table may have (a row of fixes is well under a kilobyte).
MAX_LINE_BYTES = 2**20

# What reading a (possibly gzip) stream can raise when the file is damaged.
READ_ERRORS = (OSError, EOFError, zlib.error)


def damaged(exc: Exception, source: str) -> InputError:
    """The error for a file whose (compressed) bytes cannot be read to the end."""
    return InputError(
        f"cannot read compressed data: {exc}",
        source=source,
        hint="the .gz file is damaged or truncated",
    )


def check_readable(path: Path) -> None:
    """Raise InputError unless ``path`` is an existing file."""
    if not path.exists():
        raise InputError("no such file", source=str(path), hint="check the path")
    if path.is_dir():
        raise InputError("is a directory, not a file", source=str(path))


@contextmanager
def open_bytes(path: Path) -> Iterator[io.BufferedIOBase]:
    """The file as bytes, decompressed when its name ends in ``.gz``."""
    check_readable(path)
    with ExitStack() as stack:
        try:
            handle: io.BufferedIOBase = stack.enter_context(path.open("rb"))
        except OSError as exc:
            raise InputError(f"cannot open: {exc.strerror or exc}", source=str(path)) from None
        if path.suffix.lower() == ".gz":
            handle = stack.enter_context(gzip.GzipFile(fileobj=handle, mode="rb"))
        yield handle


def text_lines(raw: io.BufferedIOBase, source: str) -> Iterator[str]:
    """Decode a byte stream line by line as UTF-8, naming the line of the first bad byte.

    Decoding per line is exact for UTF-8 (no character spans a newline) and
    gives the line number that a whole-file decode cannot. A leading BOM is
    dropped. NUL bytes are refused: no text format uses them, and they are
    the mark of a binary file or of UTF-16 text (Excel's "Unicode text").
    """
    try:
        for number, line in enumerate(iter(lambda: raw.readline(MAX_LINE_BYTES + 1), b""), 1):
            if len(line) > MAX_LINE_BYTES:
                raise InputError(
                    f"a line longer than {MAX_LINE_BYTES // 2**20} MiB",
                    source=source,
                    line=number,
                    hint="no table of fixes has such lines: is this the right file? "
                    "(a line is read only up to the limit, so memory stays bounded)",
                )
            if number == 1 and line.startswith(b"\xef\xbb\xbf"):
                line = line[3:]
            if b"\x00" in line:
                raise InputError(
                    "NUL bytes in the text: a binary file, or UTF-16 text",
                    source=source,
                    line=number,
                    hint="save the file as UTF-8 text or pass the right format",
                )
            try:
                yield line.decode("utf-8")
            except UnicodeDecodeError as exc:
                raise InputError(
                    f"not UTF-8 text (byte 0x{line[exc.start]:02x} at character {exc.start + 1})",
                    source=source,
                    line=number,
                    hint="is this a binary file? save it as UTF-8 text or pass the right format",
                ) from None
    except READ_ERRORS as exc:
        raise damaged(exc, source) from None
