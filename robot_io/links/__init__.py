"""Robot links: how the online supervisor talks to a KUKA controller's program override.

:class:`~robot_io.links.base.RobotLink` is the protocol; one module per member and per simulated peer:
KukaVarProxy (:mod:`~robot_io.links.kvp`, :mod:`~robot_io.links.kvp_sim`) and RSI
(:mod:`~robot_io.links.rsi`, :mod:`~robot_io.links.rsi_process`, :mod:`~robot_io.links.rsi_sim`, and the
controller's ETHERNET configuration :mod:`~robot_io.links.rsi_config`)."""

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
    AXIS_LIMIT,
    DELAY_MAX,
    IPOC_MAX,
    MAX_PACKET_BYTES,
    ORIENTATION_LIMIT_DEG,
    POSITION_LIMIT_MM,
    SHORT_FIRST_PACKET_BYTES,
    RobTelegram,
    RsiServer,
    SenTelegram,
    build_rob,
    build_sen,
    parse_rob,
    parse_sen,
)
from robot_io.links.rsi_config import (
    AXIS_TAGS,
    POSE_TAGS,
    RsiConfig,
    load_rsi_config,
    parse_rsi_config,
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
    "AXIS_LIMIT",
    "AXIS_TAGS",
    "DELAY_MAX",
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
    "ORIENTATION_LIMIT_DEG",
    "OVERRIDE_MAX_PERCENT",
    "OVERRIDE_MIN_PERCENT",
    "OV_PRO",
    "POSE_TAGS",
    "POSITION_LIMIT_MM",
    "ProtocolError",
    "RobTelegram",
    "RobotLink",
    "RsiConfig",
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
    "load_rsi_config",
    "override_to_int",
    "pack_reply",
    "pack_request",
    "parse_reply",
    "parse_request",
    "parse_rob",
    "parse_rsi_config",
    "parse_sen",
    "read_reply",
]
