"""Reading a user's TOML input file (scenario, batch) with every failure as one line.

Only a regular file of at most ``max_bytes`` is read (a FIFO, a device such as ``/dev/zero`` or
a directory is refused before any read: opening is non-blocking and the type is checked on the
open descriptor); the text must be UTF-8 (a UTF-16/32 byte-order mark is named as such); the TOML
may nest tables and arrays at most ``MAX_DEPTH`` deep.
"""

from __future__ import annotations

import codecs
import os
import stat
import tomllib
from pathlib import Path

MAX_BYTES = 4 * 1024 * 1024
MAX_DEPTH = 32
_WIDE_BOMS = {
    codecs.BOM_UTF32_LE: "UTF-32",
    codecs.BOM_UTF32_BE: "UTF-32",
    codecs.BOM_UTF16_LE: "UTF-16",
    codecs.BOM_UTF16_BE: "UTF-16",
}


def read_text(path: Path, error: type[Exception], what: str, max_bytes: int = MAX_BYTES) -> str:
    """The UTF-8 text of the regular file ``path``; ``error(one line)`` otherwise."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as exc:
        raise error(f"{path}: cannot read {what} file ({exc.strerror})") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise error(f"{path}: {what} file is not a regular file")
        if info.st_size > max_bytes:
            raise error(f"{path}: {what} file is {info.st_size} bytes, more than the {max_bytes} allowed")
        data = _read_at_most(fd, max_bytes + 1)
    except OSError as exc:
        raise error(f"{path}: cannot read {what} file ({exc.strerror})") from None
    finally:
        os.close(fd)
    if len(data) > max_bytes:
        raise error(f"{path}: {what} file grew over the {max_bytes} bytes allowed while being read")
    for bom, name in _WIDE_BOMS.items():
        if data.startswith(bom):
            raise error(f"{path}: {what} file is {name}-encoded; save it as UTF-8")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise error(f"{path}: {what} file is not UTF-8 (byte {exc.start}, line {line})") from None


def _read_at_most(fd: int, n: int) -> bytes:
    parts, left = [], n
    while left > 0 and (part := os.read(fd, min(left, 1 << 20))):
        parts.append(part)
        left -= len(part)
    return b"".join(parts)


def parse_toml(text: str, source: str, error: type[Exception]) -> dict:
    """The TOML document ``text``; ``error(one line naming source)`` on bad syntax or nesting
    deeper than ``MAX_DEPTH``."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{source}: not valid TOML: {exc}") from None
    except RecursionError:
        raise error(f"{source}: TOML nested too deeply") from None
    if _depth(data) > MAX_DEPTH:
        raise error(f"{source}: TOML nested more than {MAX_DEPTH} levels deep")
    return data


def _depth(node: object) -> int:
    """Nesting depth of tables/arrays, iteratively (no recursion on hostile input)."""
    deepest, stack = 0, [(node, 0)]
    while stack:
        n, d = stack.pop()
        children = n.values() if isinstance(n, dict) else n if isinstance(n, list) else None
        if children is None:
            continue
        deepest = max(deepest, d + 1)
        if deepest > MAX_DEPTH:
            return deepest
        stack.extend((c, d + 1) for c in children)
    return deepest
