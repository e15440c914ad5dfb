"""RSI telegrams: the ``<Rob>`` a KUKA controller sends every cycle and the ``<Sen>`` the PC answers.

Layouts of KUKA_IO.md §2.3. The parsers treat every datagram as untrusted:

- size-bounded (``max_bytes``, :data:`MAX_PACKET_BYTES` by default) before any parsing;
- ASCII-compatible encodings only (ASCII, UTF-8, ISO-8859-x, what controllers send): a datagram
  with a NUL byte, a UTF-16 byte-order mark or a UTF-16/32 declaration is refused before the XML
  parser sees it;
- XML through ``defusedxml`` with DTDs forbidden: no entity expansion (billion laughs), no external
  entities, no DTD at all;
- attribute and element names matched case-insensitively (``Type`` and ``TYPE`` both occur);
- the ``<Dat TaskType="b">`` wrapper of older configurations accepted (its children are read as the
  root's);
- ``IPOC`` must be an unsigned 64-bit decimal integer; its text is echoed exactly as received;
- every value read is range-checked: poses and axes finite and inside :data:`POSITION_LIMIT_MM`,
  :data:`ORIENTATION_LIMIT_DEG`, :data:`AXIS_LIMIT`; ``<Delay D>`` a count in [0, :data:`DELAY_MAX`];
  the override read-back a finite percentage in [0, 100];
- an XML declaration naming an encoding that neither expat nor Python knows
  (``encoding="UTF-1"``) is a malformed packet like any other.

Every refusal is a :class:`~robot_io.links.base.ProtocolError` saying why.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from xml.etree.ElementTree import Element, ParseError

import defusedxml.ElementTree as safe_et
from defusedxml import DefusedXmlException

from robot_io.links.base import OVERRIDE_MAX_PERCENT, OVERRIDE_MIN_PERCENT, LinkError, ProtocolError
from robot_io.links.rsi_config import AXIS_TAGS, POSE_TAGS

__all__ = [
    "AXIS_LIMIT",
    "CORRECTION_DIGITS",
    "DELAY_MAX",
    "IPOC_MAX",
    "MAX_PACKET_BYTES",
    "ORIENTATION_LIMIT_DEG",
    "POSITION_LIMIT_MM",
    "RobTelegram",
    "SenTelegram",
    "build_rob",
    "build_sen",
    "parse_rob",
    "parse_sen",
]

#: Decimals of a non-zero correction value (RKorr: mm and deg): 0.1 µm, below any path resolution.
CORRECTION_DIGITS = 4
#: Largest datagram parsed [bytes]; a full ``<Rob>`` with poses, currents and Tech is about 1.2 kB.
MAX_PACKET_BYTES = 4096
#: Largest IPOC (an unsigned 64-bit counter, ros-industrial's ``unsigned long long``).
IPOC_MAX = 2**64 - 1
#: Plausibility bounds of what a ``<Rob>`` reports. A value outside is a corrupt or forged telegram
#: (dropped as malformed), not a robot state; generous on purpose, they are not joint limits.
#: Cartesian X, Y, Z [mm]: 100 m, beyond any cell with its linear track.
POSITION_LIMIT_MM = 100_000.0
#: Cartesian A, B, C [deg]: KUKA reports them in (−180, 180].
ORIENTATION_LIMIT_DEG = 360.0
#: Axis values A1..A6, E1..E6 [deg, or mm for a linear external axis]: 277 turns of an endless axis
#: or a 100 m track.
AXIS_LIMIT = 100_000.0
#: ``<Delay D>`` (late-packet count, a KRL LONG) at most this.
DELAY_MAX = 2**31 - 1
_DIGITS = re.compile(r"^[0-9]{1,20}$")
_POSE_KEYS = POSE_TAGS
_AXIS_KEYS = AXIS_TAGS[:6]
#: An XML declaration's encoding name (first bytes of the datagram only).
_DECLARED_ENCODING = re.compile(rb"^\s*<\?xml[^>]{0,200}?encoding\s*=\s*[\"']([A-Za-z0-9._-]{1,40})[\"']",
                                re.IGNORECASE)
_WIDE_ENCODINGS = ("utf16", "utf32", "ucs2", "ucs4", "unicode")
_BOMS = (b"\xff\xfe", b"\xfe\xff")


def _ascii_compatible(data: bytes, n: int) -> None:
    """Refuse what is not in an ASCII-compatible encoding (UTF-16/32) before the XML parser runs."""
    if b"\x00" in data:
        raise ProtocolError("rsi", "NUL byte: UTF-16/UTF-32 or binary data; RSI telegrams are ASCII", n)
    if data.startswith(_BOMS):
        raise ProtocolError("rsi", "UTF-16 byte-order mark; RSI telegrams are ASCII", n)
    m = _DECLARED_ENCODING.match(data)
    if m is not None:
        name = m.group(1).decode("ascii").lower().replace("-", "").replace("_", "")
        if name.startswith(_WIDE_ENCODINGS):
            raise ProtocolError("rsi", f"declared encoding {m.group(1).decode()!r}; RSI telegrams are "
                                       "ASCII", n)


def _root(data: bytes, tag: str, max_bytes: int) -> tuple[dict[str, str], list[Element], bool]:
    """(root attributes with lower-case names, body elements, ``<Dat>`` wrapper seen) of an RSI
    telegram; raises ProtocolError."""
    n = len(data)
    if n > max_bytes:
        raise ProtocolError("rsi", f"larger than {max_bytes} bytes", n)
    if n == 0:
        raise ProtocolError("rsi", "empty datagram", n)
    _ascii_compatible(data, n)
    try:
        root = safe_et.fromstring(data, forbid_dtd=True, forbid_entities=True, forbid_external=True)
    except DefusedXmlException as e:
        raise ProtocolError("rsi", f"refused XML feature: {type(e).__name__}", n) from None
    except (ParseError, ValueError) as e:   # UnicodeError is a ValueError
        raise ProtocolError("rsi", f"not well-formed XML: {e}", n) from None
    except LookupError as e:   # expat hands a declared encoding it lacks to Python's codecs
        raise ProtocolError("rsi", f"unknown XML encoding: {str(e)[:60]}", n) from None
    if root.tag.lower() != tag.lower():
        raise ProtocolError("rsi", f"root element <{root.tag[:40]}>, expected <{tag}>", n)
    body: list[Element] = []
    dat = False
    for child in root:
        if child.tag.lower() == "dat":
            body.extend(child)
            dat = True
        else:
            body.append(child)
    return {k.lower(): v for k, v in root.attrib.items()}, body, dat


def _ipoc(body: list[Element], size: int) -> tuple[int, str]:
    texts = [e.text for e in body if e.tag.lower() == "ipoc"]
    if len(texts) != 1:
        raise ProtocolError("rsi", f"{len(texts)} <IPOC> elements, expected one", size)
    text = (texts[0] or "").strip()
    if not _DIGITS.match(text) or int(text) > IPOC_MAX:
        raise ProtocolError("rsi", f"IPOC {text[:30]!r} is not an unsigned 64-bit integer", size)
    return int(text), text


#: Elements whose attributes must all be finite numbers (poses, axes, the late counter,
#: corrections); other elements keep only their numeric attributes.
_NUMERIC = frozenset({"RIST", "RSOL", "AIPOS", "ASPOS", "EIPOS", "ESPOS", "MACUR", "DELAY", "RKORR", "AKORR"})
_CARTESIAN = {"X": POSITION_LIMIT_MM, "Y": POSITION_LIMIT_MM, "Z": POSITION_LIMIT_MM,
              "A": ORIENTATION_LIMIT_DEG, "B": ORIENTATION_LIMIT_DEG, "C": ORIENTATION_LIMIT_DEG}
_AXES = dict.fromkeys(AXIS_TAGS, AXIS_LIMIT)
#: |value| bound by element and attribute (upper case) of what the server reads; unit in the names.
_LIMITS: dict[str, dict[str, float]] = {"RIST": _CARTESIAN, "RSOL": _CARTESIAN, "AIPOS": _AXES,
                                        "ASPOS": _AXES, "EIPOS": _AXES, "ESPOS": _AXES}


def _floats(elem: Element, size: int) -> dict[str, float]:
    tag = elem.tag.upper()
    strict = tag in _NUMERIC
    limits = _LIMITS.get(tag, {})
    out: dict[str, float] = {}
    for k, v in elem.attrib.items():
        try:
            x = float(v)
        except ValueError:
            x = math.nan
        if not math.isfinite(x):
            if strict:
                raise ProtocolError("rsi", f"<{elem.tag[:40]}> {k[:40]}={v[:30]!r} is not a finite number",
                                    size)
            continue
        key = k.upper()
        bound = limits.get(key)
        if bound is not None and abs(x) > bound:
            raise ProtocolError("rsi", f"<{elem.tag[:40]}> {k[:40]}={v[:30]!r} is out of range (|value| "
                                       f"<= {bound:g})", size)
        out[key] = x
    if tag == "DELAY":
        d = out.get("D")
        if d is not None and not (d == int(d) and 0 <= d <= DELAY_MAX):
            raise ProtocolError("rsi", f"<{elem.tag}> D={d:g} is not a late-packet count (0..{DELAY_MAX})",
                                size)
    return out


def _percent(elem: Element, size: int) -> float:
    """The override read-back element's value [percent], range-checked."""
    text = (elem.text or "").strip()
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not (math.isfinite(v) and OVERRIDE_MIN_PERCENT <= v <= OVERRIDE_MAX_PERCENT):
        raise ProtocolError("rsi", f"<{elem.tag[:40]}> {text[:30]!r} is not an override in "
                                   f"[{OVERRIDE_MIN_PERCENT}, {OVERRIDE_MAX_PERCENT}] %", size)
    return v


@dataclass(frozen=True)
class RobTelegram:
    """A parsed ``<Rob>`` telegram (robot → PC).

    Attributes:
        ipoc: interpolation counter [ms] (opaque, unsigned 64-bit).
        ipoc_text: ``IPOC`` as received (what the reply echoes).
        type: the root ``Type``/``TYPE`` attribute, ``None`` when absent.
        poses: elements with numeric attributes, by upper-case tag (``"RIST"`` → {"X": mm, ..., "C":
            deg}, ``"AIPOS"`` → {"A1": deg, ...}, ``"DELAY"`` → {"D": count}), range-checked.
        values: text elements by upper-case tag (``"OVPRO"`` → "100").
        dat: the body was wrapped in ``<Dat>``.
        override: ``$OV_PRO`` the controller reports in the override read-back element (``<OvPro>``
            unless configured otherwise) [percent], checked to lie in [0, 100]; ``None`` when absent.
    """

    ipoc: int
    ipoc_text: str
    type: str | None
    poses: dict[str, dict[str, float]] = field(default_factory=dict)
    values: dict[str, str] = field(default_factory=dict)
    dat: bool = False
    override: float | None = None

    @property
    def rist(self) -> dict[str, float] | None:
        """Actual Cartesian pose (X, Y, Z [mm]; A, B, C [deg]) or ``None``."""
        return self.poses.get("RIST")

    @property
    def aipos(self) -> dict[str, float] | None:
        """Actual axis angles A1..A6 [deg] or ``None``."""
        return self.poses.get("AIPOS")

    @property
    def delay(self) -> int | None:
        """The controller's late-packet counter (``<Delay D=..>``) or ``None``."""
        d = self.poses.get("DELAY", {}).get("D")
        return None if d is None else int(d)

    @property
    def ov_pro(self) -> float | None:
        """``$OV_PRO`` the controller reports [percent] (:attr:`override`), ``None`` when absent."""
        return self.override


def parse_rob(data: bytes, max_bytes: int = MAX_PACKET_BYTES,
              override_tag: str | None = "OvPro") -> RobTelegram:
    """Parse a ``<Rob>`` datagram; raises :class:`~robot_io.links.base.ProtocolError`.

    ``override_tag`` is the element reporting ``$OV_PRO`` (the ETHERNET configuration's SEND element
    wired to an OV_PRO object), ``None`` when the controller sends none.
    """
    attrs, body, dat = _root(data, "Rob", max_bytes)
    ipoc, text = _ipoc(body, len(data))
    poses: dict[str, dict[str, float]] = {}
    values: dict[str, str] = {}
    override = None
    over = None if override_tag is None else override_tag.upper()
    for e in body:
        tag = e.tag.upper()
        if tag == "IPOC":
            continue
        if tag == over:
            if override is not None:
                raise ProtocolError("rsi", f"two <{e.tag[:40]}> override elements", len(data))
            override = _percent(e, len(data))
        if e.attrib:
            poses[tag] = _floats(e, len(data))
        else:
            values[tag] = (e.text or "").strip()
    return RobTelegram(ipoc, text, attrs.get("type"), poses, values, dat, override)


@dataclass(frozen=True)
class SenTelegram:
    """A parsed ``<Sen>`` telegram (PC → robot).

    Attributes:
        ipoc, ipoc_text: the echoed counter.
        type: the root ``Type`` attribute (must equal the config's SENTYPE), ``None`` when absent.
        override: the override channel's value [percent], ``None`` when the element is absent (the
            controller then holds the last value: HOLDON=1).
        corrections: correction elements by upper-case tag (``"RKORR"``, ``"AKORR"``, ``"AK"``).
    """

    ipoc: int
    ipoc_text: str
    type: str | None
    override: int | None
    corrections: dict[str, dict[str, float]] = field(default_factory=dict)


def parse_sen(data: bytes, override_tag: str | None = "OvProW",
              max_bytes: int = MAX_PACKET_BYTES) -> SenTelegram:
    """Parse a ``<Sen>`` datagram; raises :class:`~robot_io.links.base.ProtocolError`."""
    attrs, body, _ = _root(data, "Sen", max_bytes)
    ipoc, text = _ipoc(body, len(data))
    override = None
    over = None if override_tag is None else override_tag.upper()
    corrections: dict[str, dict[str, float]] = {}
    for e in body:
        tag = e.tag.upper()
        if tag == over:
            raw = (e.text or "").strip()
            if not re.match(r"^-?[0-9]{1,6}$", raw):
                raise ProtocolError("rsi", f"<{e.tag}> {raw[:30]!r} is not an integer", len(data))
            override = int(raw)
        elif e.attrib:
            corrections[tag] = _floats(e, len(data))
    return SenTelegram(ipoc, text, attrs.get("type"), override, corrections)


def build_sen(ipoc_text: str, override_percent: int | None, sentype: str = "ImFree",
              override_tag: str = "OvProW", correction: str | None = "RKorr", dat: bool = False,
              estr: str | None = None, correction_tags: Sequence[str] | None = None,
              correction_values: Sequence[float] | None = None) -> bytes:
    """A ``<Sen>`` reply: the correction, the override channel (omitted when ``None``), the IPOC echo.

    ``ipoc_text`` is echoed verbatim (pass :attr:`RobTelegram.ipoc_text`); ``correction`` is the
    correction element, ``None`` for none; its attributes are ``correction_tags``
    (default: X..C for ``"RKorr"``, A1..A6 for ``"AKorr"``; required for any other element, e.g.
    ros-industrial's ``"AK"``), their values ``correction_values`` (one finite number per tag, in
    the element's units: mm and deg for RKorr; default zeros, written ``0.0``); ``estr`` is free
    ASCII text shown on the HMI (XML-escaped).
    """
    parts = [f'<Sen Type="{sentype}">']
    if dat:
        parts.append('<Dat TaskType="b">')
    if estr is not None:
        safe = (estr.encode("ascii", "replace").decode().replace("&", "&amp;").replace("<", "&lt;")
                .replace(">", "&gt;"))
        parts.append(f"<EStr>{safe}</EStr>")
    if correction is not None:
        tags = (correction_tags if correction_tags is not None
                else _POSE_KEYS if correction == "RKorr" else _AXIS_KEYS if correction == "AKorr" else None)
        if not tags:
            raise LinkError("rsi", f"correction element {correction!r} needs its correction_tags")
        if correction_values is None:
            parts.append(f"<{correction} " + " ".join(f'{t}="0.0"' for t in tags) + "/>")
        else:
            vals = [float(v) for v in correction_values]
            if len(vals) != len(tags) or not all(math.isfinite(v) for v in vals):
                raise LinkError("rsi", f"<{correction}> needs {len(tags)} finite correction values, got "
                                       f"{len(vals)}")
            parts.append(f"<{correction} " + " ".join(f'{t}="{v:.{CORRECTION_DIGITS}f}"'
                                                      for t, v in zip(tags, vals, strict=True)) + "/>")
    if override_percent is not None:
        parts.append(f"<{override_tag}>{int(override_percent)}</{override_tag}>")
    parts.append(f"<IPOC>{ipoc_text}</IPOC>")
    if dat:
        parts.append("</Dat>")
    parts.append("</Sen>")
    return "".join(parts).encode("ascii")


def build_rob(ipoc: int, rist_mm_deg: tuple[float, ...] | None = None,
              aipos_deg: tuple[float, ...] | None = None, delay: int | None = 0,
              ov_pro_percent: float | None = None, type_attr: str = "Type", dat: bool = False,
              precision: int = 4, override_tag: str = "OvPro") -> bytes:
    """A ``<Rob>`` telegram as a controller sends it (for the simulated controller and tests).

    ``rist_mm_deg`` = (X, Y, Z [mm], A, B, C [deg]); ``aipos_deg`` = A1..A6 [deg]; ``type_attr`` is
    the spelling of the root attribute (``"Type"`` on real controllers, ``"TYPE"`` in ROS sims);
    ``ov_pro_percent`` goes into the ``override_tag`` element.
    """
    p = int(precision)
    parts = [f'<Rob {type_attr}="KUKA">']
    if dat:
        parts.append('<Dat TaskType="b">')
    if rist_mm_deg is not None:
        parts.append("<RIst " + " ".join(f'{k}="{v:.{p}f}"' for k, v in zip(_POSE_KEYS, rist_mm_deg,
                                                                          strict=True)) + "/>")
    if aipos_deg is not None:
        parts.append("<AIPos " + " ".join(f'{k}="{v:.{p}f}"' for k, v in zip(_AXIS_KEYS, aipos_deg,
                                                                           strict=True)) + "/>")
    if delay is not None:
        parts.append(f'<Delay D="{int(delay)}"/>')
    if ov_pro_percent is not None:
        parts.append(f"<{override_tag}>{int(round(ov_pro_percent))}</{override_tag}>")
    parts.append(f"<IPOC>{int(ipoc)}</IPOC>")
    if dat:
        parts.append("</Dat>")
    parts.append("</Rob>")
    return "".join(parts).encode("ascii")
