"""Reading an airframe's gains file (TOML); each controller maps the table onto its own
dataclasses and rejects unknown or missing keys with a :class:`GainsError`."""

from __future__ import annotations

import tomllib
from pathlib import Path


class GainsError(ValueError):
    """A gains file is unreadable or invalid; the message names the file and the key."""


def read_gains_toml(path: str | Path | None, default: Path) -> tuple[dict, str]:
    """The table of ``path`` (``default`` when None) and the file name for messages."""
    p = Path(path) if path is not None else default
    try:
        with p.open("rb") as fh:
            return tomllib.load(fh), str(p)
    except OSError as exc:
        raise GainsError(f"{p}: cannot read gains file ({exc.strerror})") from None
    except tomllib.TOMLDecodeError as exc:
        raise GainsError(f"{p}: not valid TOML: {exc}") from None
