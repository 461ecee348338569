"""Decoding one received UDP datagram into MAVLink messages, classifying what is wrong with it.

Each datagram is parsed on its own (a fresh parser), so a truncated or corrupt datagram can never
corrupt the parse of the next one. MAVLink 1 and 2 frames are both accepted (common dialect).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from pymavlink.dialects.v20 import common as mav

from sim.mavlink.signing import parser as make_parser

# anomaly kinds (keys of VehicleLink.stats)
GARBAGE = "garbage"  # bytes that do not start a MAVLink frame
BAD_CRC = "bad_crc"
BAD_LENGTH = "bad_length"
TRUNCATED = "truncated"  # a frame cut short by the end of the datagram
UNKNOWN_ID = "unknown_message_id"  # not a common-dialect message
MALFORMED = "malformed"  # any other decode failure (bad header, flags, payload)
BAD_SIGNATURE = "bad_signature"  # signing on: unsigned, wrongly signed or replayed frame
DECODE_ERRORS = frozenset({GARBAGE, BAD_CRC, BAD_LENGTH, TRUNCATED, UNKNOWN_ID, MALFORMED, BAD_SIGNATURE})


@dataclass
class Decoded:
    messages: list[mav.MAVLink_message] = field(default_factory=list)
    anomalies: list[tuple[str, str]] = field(default_factory=list)  # (kind, detail)


def _kind(reason: str) -> str:
    if reason == "Bad prefix":
        return GARBAGE
    if reason == "Invalid signature":
        return BAD_SIGNATURE
    if "CRC" in reason:
        return BAD_CRC
    if "length" in reason:
        return BAD_LENGTH
    return MALFORMED


_FRAME_STARTS = (mav.PROTOCOL_MARKER_V2, mav.PROTOCOL_MARKER_V1)


def decode_datagram(data: bytes, signing: mav.MAVLinkSigning | None = None) -> Decoded:
    """Every frame in ``data`` (with ``signing``: only frames signed with its key); never raises.
    A datagram that does not start with a frame is garbage as a whole (senders put frames at the
    start; scanning hostile bytes for frame starts costs about a millisecond per kilobyte)."""
    out = Decoded()
    if data and data[0] not in _FRAME_STARTS:
        out.anomalies.append((GARBAGE, f"{len(data)} bytes without a frame start"))
        return out
    parser = make_parser(signing)
    try:
        for msg in parser.parse_buffer(data) or ():
            if isinstance(msg, mav.MAVLink_bad_data):
                out.anomalies.append((_kind(msg.reason), msg.reason))
            elif isinstance(msg, mav.MAVLink_unknown):
                out.anomalies.append((UNKNOWN_ID, f"message id {msg.get_msgId()}"))
            else:
                out.messages.append(msg)
    except Exception as exc:  # noqa: BLE001 - pymavlink raises assorted types on hostile input
        out.anomalies.append((MALFORMED, f"{type(exc).__name__}: {exc}"))
        return out
    if parser.buf_len() > 0:
        out.anomalies.append((TRUNCATED, f"{parser.buf_len()} bytes left of an incomplete frame"))
    return out
