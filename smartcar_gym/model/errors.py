"""Exceptions and warnings of the robot-model loader."""

from __future__ import annotations

import os
import xml.parsers.expat
from pathlib import Path


class ModelError(ValueError):
    """A robot description that cannot be loaded: says where (file, line) and what was expected."""

    def __init__(
        self, message: str, *, file: str | os.PathLike | None = None, line: int | None = None
    ) -> None:
        self.message = message
        self.file = None if file is None else str(file)
        self.line = line
        super().__init__(str(self))

    def __str__(self) -> str:
        if self.file is None:
            return self.message
        where = self.file if self.line is None else f"{self.file}:{self.line}"
        return f"{where}: {self.message}"


def xml_syntax_error(
    exc: xml.parsers.expat.ExpatError, file: str | os.PathLike | None, note: str = ""
) -> ModelError:
    """ModelError for an expat error: file, line, column, the reason and what was expected."""
    reason = xml.parsers.expat.ErrorString(exc.code)
    return ModelError(
        f"XML syntax error: {reason} (column {exc.offset + 1}); expected well-formed XML{note}",
        file=file,
        line=exc.lineno,
    )


def read_utf8(path: str | os.PathLike) -> str:
    """Text of the file at ``path``; ModelError naming file, line and byte if it is not UTF-8."""
    data = Path(path).read_bytes()
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        column = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        raise ModelError(
            f"not UTF-8 text: byte 0x{data[exc.start]:02x} (column {column}) cannot be decoded "
            f"({exc.reason}); expected a UTF-8 encoded file (re-save it as UTF-8)",
            file=path,
            line=line,
        ) from None


class ModelDefectWarning(UserWarning):
    """A physically implausible or inconsistent model (and each repair applied to it)."""


class LegacyXacroWarning(FutureWarning):
    """A file written in ROS-indigo xacro (unprefixed tags) that was upgraded before expansion."""


class XacroWarning(UserWarning):
    """A warning xacro itself would have printed to stderr."""
