"""MAVLink 2 message signing: the secret key and the signing state of one link.

The key file holds a passphrase; the key is its SHA-256 digest (what MAVProxy's
``signing setup PASSPHRASE`` derives, so the same passphrase works there). The key is never
logged or shown: error messages name only the file. With signing on, the link signs what it
sends and accepts only frames signed with the key (unsigned and MAVLink 1 frames are refused);
pymavlink's per-stream timestamps refuse replayed frames.
"""

from __future__ import annotations

import hashlib
import stat
import time
from pathlib import Path

from pymavlink.dialects.v20 import common as mav

_MAX_KEY_FILE_BYTES = 4096
_SIGNING_EPOCH_S = 1_420_070_400  # 2015-01-01T00:00:00Z, the signing timestamp's origin


class SigningKeyError(ValueError):
    """The key file is missing, not a regular file, empty or too large (one-line message)."""


def load_key(path: Path) -> bytes:
    """The 32-byte signing key from the passphrase in ``path`` (surrounding whitespace ignored)."""
    try:
        info = path.stat()
        if not stat.S_ISREG(info.st_mode):
            raise SigningKeyError(f"{path}: MAVLink signing key file is not a regular file")
        if info.st_size > _MAX_KEY_FILE_BYTES:
            raise SigningKeyError(f"{path}: MAVLink signing key file is over {_MAX_KEY_FILE_BYTES} bytes")
        passphrase = path.read_bytes().strip()
    except OSError as exc:
        raise SigningKeyError(f"{path}: cannot read the MAVLink signing key: {exc.strerror}") from None
    if not passphrase:
        raise SigningKeyError(f"{path}: MAVLink signing key file is empty")
    return hashlib.sha256(passphrase).digest()


class _VerifyFirst(mav.MAVLink):
    """pymavlink records a stream's timestamp before checking the signature, so one forged frame
    with a far-future timestamp would lock the real sender out; here the signature is checked
    first and only a genuine frame moves the timestamp."""

    def check_signature(self, msgbuf: bytearray, srcSystem: int, srcComponent: int) -> bool:
        digest = hashlib.sha256(self.signing.secret_key + bytes(msgbuf[:-6])).digest()[:6]
        if digest != bytes(msgbuf[-6:]):
            return False
        return super().check_signature(msgbuf, srcSystem, srcComponent)


def signing_state(key: bytes) -> mav.MAVLinkSigning:
    """Signing state for one link: signs outgoing frames, accepts only signed ones."""
    s = mav.MAVLinkSigning()
    s.secret_key = key
    s.sign_outgoing = True
    s.timestamp = int((time.time() - _SIGNING_EPOCH_S) * 100_000)  # units of 10 us
    return s


def parser(signing: mav.MAVLinkSigning | None) -> mav.MAVLink:
    """A fresh robust parser sharing the link's signing state (``None``: no signing)."""
    p = _VerifyFirst(None) if signing is not None else mav.MAVLink(None)
    p.robust_parsing = True
    if signing is not None:
        p.signing = signing
    return p
