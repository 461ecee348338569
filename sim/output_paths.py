"""Output files named after user input stay inside the folder chosen for them."""

from __future__ import annotations

from pathlib import Path


class OutputPathError(ValueError):
    """An output file name would leave its folder (one-line message)."""


def path_under(folder: Path, filename: str) -> Path:
    """``folder / filename``, or OutputPathError (one line) if that would leave ``folder`` (a name
    with a path separator, ``..`` or an absolute path)."""
    path = folder / filename
    if Path(filename).name != filename or not path.resolve().is_relative_to(folder.resolve()):
        raise OutputPathError(f"{filename!r}: a file name must not leave {folder}/")
    return path
