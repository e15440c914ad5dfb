"""The controller's RSI ETHERNET configuration, read from the file the controller itself loads.

An RSI ``ETHERNET`` object is configured by an XML file in
``C:\\KRC\\ROBOTER\\Config\\User\\Common\\SensorInterface`` (KUKA_IO.md §2.1, §2.3)::

    <ROOT>
      <CONFIG>
        <IP_NUMBER>192.168.1.25</IP_NUMBER>  <PORT>59152</PORT>     the PC server's address
        <SENTYPE>ImFree</SENTYPE>                                     <Sen Type="..."> of the replies
        <ONLYSEND>FALSE</ONLYSEND>                                    TRUE: the robot wants no reply
      </CONFIG>
      <SEND><ELEMENTS>                                                robot -> PC (<Rob>)
        <ELEMENT TAG="DEF_RIst" TYPE="DOUBLE" INDX="INTERNAL"/>
        <ELEMENT TAG="OvPro" TYPE="LONG" INDX="21"/>                  $OV_PRO read back
      </ELEMENTS></SEND>
      <RECEIVE><ELEMENTS>                                             PC -> robot (<Sen>)
        <ELEMENT TAG="AK.A1" TYPE="DOUBLE" INDX="1" HOLDON="1"/> ...  correction <AK A1=".." .../>
        <ELEMENT TAG="OvProW" TYPE="LONG" INDX="20" HOLDON="1"/>      override channel <OvProW>
      </ELEMENTS></RECEIVE>
    </ROOT>

:func:`load_rsi_config` reads that file unchanged (give the PC the controller's own copy, so the two
cannot disagree) into an :class:`RsiConfig`: what the server's replies must look like. Rules:

- **correction element**: the RECEIVE elements ``NAME.ATTR`` of TYPE DOUBLE group into elements
  ``<NAME ATTR=".."/>``; a group whose attributes are Cartesian (X, Y, Z, A, B, C) or axes (A1..A6,
  E1..E6) is a correction. One Cartesian group wins over an axis group (RKorr over AKorr in a
  configuration that has both); two of the same kind are ambiguous (error). No group: no
  correction element is sent.
- **override channel**: the RECEIVE element named ``override_tag`` (``OvProW``) of TYPE LONG or
  DOUBLE; absent: the replies carry no override and the link cannot change ``$OV_PRO``.
- **override read-back**: the SEND element named ``override_read_tag`` (``OvPro``); absent:
  ``read_override()`` stays ``None``.
- Other RECEIVE elements (``DEF_EStr``, digital outputs, ``Tech`` …) are not sent; the controller
  holds or zeroes them by their ``HOLDON``. ``ONLYSEND TRUE`` and ``PROTOCOL TCP`` (KR C2) are
  refused by the server: it must reply over UDP.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from xml.etree.ElementTree import Element, ParseError

import defusedxml.ElementTree as safe_et
from defusedxml import DefusedXmlException

from robot_io.links.base import LinkError

__all__ = [
    "AXIS_TAGS",
    "POSE_TAGS",
    "RsiConfig",
    "load_rsi_config",
    "parse_rsi_config",
]

#: Attributes of a Cartesian correction (RKorr: X, Y, Z [mm], A, B, C [deg]).
POSE_TAGS = ("X", "Y", "Z", "A", "B", "C")
#: Attributes of an axis correction (AKorr: A1..A6 [deg], external axes E1..E6).
AXIS_TAGS = ("A1", "A2", "A3", "A4", "A5", "A6", "E1", "E2", "E3", "E4", "E5", "E6")
#: Largest configuration file read [bytes]; KUKA allows 64 channels a direction, about 6 kB.
_MAX_FILE_BYTES = 1 << 20
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_-]{0,63}$")
_NUMERIC_TYPES = ("LONG", "DOUBLE")


def _xml_name(name: str, what: str) -> str:
    if not _NAME.match(name):
        raise LinkError("rsi", f"{what} {name!r} must be an XML name (letters, digits, _)")
    return name


@dataclass(frozen=True)
class RsiConfig:
    """What the controller's ETHERNET configuration asks of the PC server's replies.

    The default is the configuration the project's KRL export assumes (KUKA_IO.md §2.4): SENTYPE
    ``ImFree``, zero ``RKorr``, override channel ``OvProW``, read-back ``OvPro``.

    Attributes:
        sentype: ``Type`` of the ``<Sen>`` root (CONFIG/SENTYPE).
        correction: element of the correction sent with zeros (``"RKorr"``, ``"AKorr"``, ros-industrial's
            ``"AK"`` …), ``None`` for none.
        correction_tags: its attributes, in the configuration's order.
        override_tag: ``<Sen>`` element of the override channel (→ MAP2OV_PRO), ``None`` for none.
        override_read_tag: ``<Rob>`` element reporting ``$OV_PRO`` [percent], ``None`` for none.
        ip_number: CONFIG/IP_NUMBER, the PC's address the controller sends to (``None`` if absent).
        port: CONFIG/PORT, the UDP port the controller sends to (``None`` if absent).
        only_send: CONFIG/ONLYSEND (the controller expects no replies).
        protocol: CONFIG/PROTOCOL (KR C2: ``"UDP"`` or ``"TCP"``; KR C4 is always UDP).
        send_tags: the ``<Rob>`` elements the controller sends (``DEF_RIst`` → ``RIst``), in order.
        source: the file read, ``None`` when built in code.
    """

    sentype: str = "ImFree"
    correction: str | None = "RKorr"
    correction_tags: tuple[str, ...] = POSE_TAGS
    override_tag: str | None = "OvProW"
    override_read_tag: str | None = "OvPro"
    ip_number: str | None = None
    port: int | None = None
    only_send: bool = False
    protocol: str = "UDP"
    send_tags: tuple[str, ...] = ()
    source: str | None = None

    def __post_init__(self) -> None:
        _xml_name(self.sentype, "SENTYPE")
        for what, name in (("override tag", self.override_tag),
                           ("override read-back tag", self.override_read_tag),
                           ("correction element", self.correction)):
            if name is not None:
                _xml_name(name, what)
        if self.correction is not None:
            if not self.correction_tags:
                raise LinkError("rsi", f"correction element {self.correction!r} has no attributes; give "
                                       "its tags (RKorr: X..C, AKorr: A1..A6)")
            for t in self.correction_tags:
                _xml_name(t, f"attribute of <{self.correction}>")
        if self.port is not None and not 1 <= self.port <= 65535:
            raise LinkError("rsi", f"PORT {self.port} is not a UDP port (1..65535)")

    @classmethod
    def from_options(cls, sentype: str = "ImFree", override_tag: str | None = "OvProW",
                     correction: str | None = "RKorr", correction_tags: tuple[str, ...] | None = None,
                     override_read_tag: str | None = "OvPro") -> RsiConfig:
        """A configuration from the server's keyword options; ``correction_tags`` defaults to
        X..C for ``RKorr`` and A1..A6 for ``AKorr`` and must be given for any other element."""
        if correction is None:
            tags: tuple[str, ...] = ()
        elif correction_tags is not None:
            tags = tuple(correction_tags)
        elif correction == "RKorr":
            tags = POSE_TAGS
        elif correction == "AKorr":
            tags = AXIS_TAGS[:6]
        else:
            raise LinkError("rsi", f"correction {correction!r}: use 'RKorr', 'AKorr' or None, or give "
                                   "correction_tags (or an RSI config file)")
        return cls(sentype=sentype, correction=correction, correction_tags=tags, override_tag=override_tag,
                   override_read_tag=override_read_tag)


def _text(config: Element, name: str) -> str | None:
    for child in config:
        if child.tag.upper() == name:
            return (child.text or "").strip()
    return None


def _elements(root: Element, section: str) -> list[Element]:
    out: list[Element] = []
    for sec in root:
        if sec.tag.upper() == section:
            for group in sec:
                if group.tag.upper() == "ELEMENTS":
                    out.extend(e for e in group if e.tag.upper() == "ELEMENT")
    return out


def _attr(e: Element, name: str) -> str:
    for k, v in e.attrib.items():
        if k.upper() == name:
            return v.strip()
    return ""


def parse_rsi_config(data: bytes, source: str = "<config>", override_tag: str = "OvProW",
                     override_read_tag: str = "OvPro") -> RsiConfig:
    """Read an ETHERNET configuration (the XML above) from bytes; raises
    :class:`~robot_io.links.base.LinkError` naming ``source`` and what to fix.

    ``override_tag``/``override_read_tag`` name the override channel and its read-back for sites
    that call them otherwise than ``OvProW``/``OvPro`` (the file does not say which channel is
    wired to MAP2OV_PRO: that is in the RSI diagram).
    """
    where = f"RSI config {source}"
    if len(data) > _MAX_FILE_BYTES:
        raise LinkError("rsi", f"{where}: larger than {_MAX_FILE_BYTES} bytes; is it the ETHERNET "
                               "configuration?")
    try:
        root = safe_et.fromstring(data, forbid_dtd=True, forbid_entities=True, forbid_external=True)
    except (DefusedXmlException, ParseError, ValueError, LookupError) as e:
        raise LinkError("rsi", f"{where}: not a well-formed ETHERNET configuration: {e}") from None
    if root.tag.upper() != "ROOT":
        raise LinkError("rsi", f"{where}: root element <{root.tag[:40]}>, expected <ROOT> (the RSI "
                               "ETHERNET object's XML)")
    configs = [c for c in root if c.tag.upper() == "CONFIG"]
    if len(configs) != 1:
        raise LinkError("rsi", f"{where}: {len(configs)} <CONFIG> sections, expected one")
    cfg = configs[0]
    sentype = _text(cfg, "SENTYPE")
    if not sentype:
        raise LinkError("rsi", f"{where}: <CONFIG><SENTYPE> is missing: it is the Type the replies "
                               "carry (<Sen Type=\"ImFree\">)")
    port_text = _text(cfg, "PORT")
    port = None
    if port_text:
        if not port_text.isdigit() or not 1 <= int(port_text) <= 65535:
            raise LinkError("rsi", f"{where}: <PORT> {port_text[:20]!r} is not a UDP port (1..65535)")
        port = int(port_text)
    only = (_text(cfg, "ONLYSEND") or "FALSE").upper()
    if only not in ("TRUE", "FALSE"):
        raise LinkError("rsi", f"{where}: <ONLYSEND> {only[:20]!r}: expected TRUE or FALSE")
    protocol = (_text(cfg, "PROTOCOL") or "UDP").upper()
    if protocol not in ("UDP", "TCP"):
        raise LinkError("rsi", f"{where}: <PROTOCOL> {protocol[:20]!r}: expected UDP or TCP")

    send_tags: list[str] = []
    read_tag = None
    for e in _elements(root, "SEND"):
        tag = _attr(e, "TAG")
        name = tag.removeprefix("DEF_").split(".", 1)[0]
        if name and name not in send_tags:
            send_tags.append(name)
        if tag.upper() == override_read_tag.upper():
            if _attr(e, "TYPE").upper() not in _NUMERIC_TYPES:
                raise LinkError("rsi", f"{where}: SEND element {tag!r} (the override read-back) must be "
                                       "LONG or DOUBLE")
            read_tag = tag

    groups: dict[str, list[str]] = {}
    over = None
    for e in _elements(root, "RECEIVE"):
        tag = _attr(e, "TAG")
        typ = _attr(e, "TYPE").upper()
        if tag.upper().startswith("DEF_"):
            continue  # INTERNAL elements (EStr, Tech): not corrections, not sent
        if "." in tag:
            name, attr = tag.split(".", 1)
            if typ == "DOUBLE":
                groups.setdefault(name, []).append(attr)
        elif tag.upper() == override_tag.upper():
            if typ not in _NUMERIC_TYPES:
                raise LinkError("rsi", f"{where}: RECEIVE element {tag!r} (the override channel) must "
                                       "be LONG or DOUBLE")
            over = tag
    pose = [n for n, a in groups.items() if {x.upper() for x in a} <= set(POSE_TAGS)]
    axes = [n for n, a in groups.items() if {x.upper() for x in a} <= set(AXIS_TAGS)]
    for kind, names in (("Cartesian", pose), ("axis", axes)):
        if len(names) > 1:
            raise LinkError("rsi", f"{where}: {len(names)} {kind} correction elements in RECEIVE "
                                   f"({', '.join(names)}); the server sends one: keep one in the file")
    correction = pose[0] if pose else axes[0] if axes else None
    try:
        return RsiConfig(sentype=sentype, correction=correction,
                         correction_tags=tuple(groups[correction]) if correction else (),
                         override_tag=over, override_read_tag=read_tag, ip_number=_text(cfg, "IP_NUMBER"),
                         port=port, only_send=only == "TRUE", protocol=protocol, send_tags=tuple(send_tags),
                         source=source)
    except LinkError as e:
        raise LinkError("rsi", f"{where}: {str(e).removeprefix('rsi: ')}") from None


def load_rsi_config(path: str | os.PathLike[str], override_tag: str = "OvProW",
                    override_read_tag: str = "OvPro") -> RsiConfig:
    """Read the controller's ETHERNET configuration file (see the module docstring and
    :func:`parse_rsi_config`); raises :class:`~robot_io.links.base.LinkError`."""
    p = Path(path)
    try:
        with p.open("rb") as f:
            data = f.read(_MAX_FILE_BYTES + 1)
    except OSError as e:
        raise LinkError("rsi", f"cannot read RSI config {p}: {e.strerror or e}") from None
    return parse_rsi_config(data, str(p), override_tag, override_read_tag)
