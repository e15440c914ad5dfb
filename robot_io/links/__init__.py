"""Robot links: how the online supervisor talks to a KUKA controller's program override.

:class:`~robot_io.links.base.RobotLink` is the protocol; one module per member and per simulated peer:
KukaVarProxy (:mod:`~robot_io.links.kvp`, :mod:`~robot_io.links.kvp_sim`) and RSI
(:mod:`~robot_io.links.rsi`, :mod:`~robot_io.links.rsi_process`, :mod:`~robot_io.links.rsi_sim`)."""

from robot_io.links.base import (
    OVERRIDE_MAX_PERCENT,
    OVERRIDE_MIN_PERCENT,
    LinkError,
    LinkStats,
    LinkStatus,
    ProtocolError,
    RobotLink,
    StatsCounter,
    override_to_int,
)
from robot_io.links.kvp import (
    FN_READ,
    FN_WRITE,
    KVP_DEFAULT_PORT,
    MAX_BODY_BYTES,
    OV_PRO,
    KvpClient,
    KvpConnection,
    KvpReply,
    KvpRequest,
    pack_reply,
    pack_request,
    parse_reply,
    parse_request,
    read_reply,
)
from robot_io.links.kvp_sim import (
    KvpServerStats,
    KvpSimServer,
)
from robot_io.links.rsi import (
    IPOC_MAX,
    MAX_PACKET_BYTES,
    SHORT_FIRST_PACKET_BYTES,
    RobTelegram,
    RsiServer,
    SenTelegram,
    build_rob,
    build_sen,
    parse_rob,
    parse_sen,
)
from robot_io.links.rsi_process import (
    SYNC_PERIOD_S,
    RsiProcessServer,
)
from robot_io.links.rsi_sim import (
    RsiSimController,
    RsiSimStats,
)

__all__ = [
    "FN_READ",
    "FN_WRITE",
    "IPOC_MAX",
    "KVP_DEFAULT_PORT",
    "KvpClient",
    "KvpConnection",
    "KvpReply",
    "KvpRequest",
    "KvpServerStats",
    "KvpSimServer",
    "LinkError",
    "LinkStats",
    "LinkStatus",
    "MAX_BODY_BYTES",
    "MAX_PACKET_BYTES",
    "OVERRIDE_MAX_PERCENT",
    "OVERRIDE_MIN_PERCENT",
    "OV_PRO",
    "ProtocolError",
    "RobTelegram",
    "RobotLink",
    "RsiProcessServer",
    "RsiServer",
    "RsiSimController",
    "RsiSimStats",
    "SHORT_FIRST_PACKET_BYTES",
    "SYNC_PERIOD_S",
    "SenTelegram",
    "StatsCounter",
    "build_rob",
    "build_sen",
    "override_to_int",
    "pack_reply",
    "pack_request",
    "parse_reply",
    "parse_request",
    "parse_rob",
    "parse_sen",
    "read_reply",
]
