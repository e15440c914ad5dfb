"""cctmill I/O across the boundary: toolpath readers (G-code, APT/CL, KUKA KRL) into one plain move
model; the KRL writer and its lint; KUKA protocols and signal sources. Own plain data types; never
imports ``planner``."""

from robot_io.apt import read_apt, read_apt_text
from robot_io.gcode import read_gcode, read_gcode_text
from robot_io.krl import (
    KrlError,
    KrlFrame,
    KrlMove,
    KrlProgramSpec,
    KrlSection,
    render_krl,
    write_krl,
)
from robot_io.krl_lint import LintProblem, lint_krl
from robot_io.krl_reader import read_krl, read_krl_text
from robot_io.kvp import KvpClient, KvpConnection
from robot_io.kvp_sim import KvpSimServer
from robot_io.readers import FORMATS, detect_format, read_toolpath
from robot_io.robot_link import LinkError, LinkStats, LinkStatus, ProtocolError, RobotLink
from robot_io.rsi import RsiServer
from robot_io.rsi_process import RsiProcessServer
from robot_io.rsi_sim import RsiSimController
from robot_io.signal_replay import ReplaySource, SignalFileError, load_signal
from robot_io.signal_source import SignalChunk, SignalSource, SourceStats
from robot_io.signal_udp import UdpSignalSender, UdpSignalSource
from robot_io.toolpath import (
    Move,
    MoveKind,
    MoveList,
    SourceRef,
    Toolpath,
    ToolpathError,
    ToolpathReader,
    ToolpathWarning,
    arc_geometry,
    summarize,
)

__all__ = [
    "FORMATS",
    "KrlError",
    "KrlFrame",
    "KrlMove",
    "KrlProgramSpec",
    "KrlSection",
    "KvpClient",
    "KvpConnection",
    "KvpSimServer",
    "LinkError",
    "LinkStats",
    "LinkStatus",
    "LintProblem",
    "Move",
    "MoveKind",
    "MoveList",
    "ProtocolError",
    "ReplaySource",
    "RobotLink",
    "RsiProcessServer",
    "RsiServer",
    "RsiSimController",
    "SignalChunk",
    "SignalFileError",
    "SignalSource",
    "SourceRef",
    "SourceStats",
    "Toolpath",
    "ToolpathError",
    "ToolpathReader",
    "ToolpathWarning",
    "UdpSignalSender",
    "UdpSignalSource",
    "arc_geometry",
    "detect_format",
    "lint_krl",
    "load_signal",
    "read_apt",
    "read_apt_text",
    "read_gcode",
    "read_gcode_text",
    "read_krl",
    "read_krl_text",
    "read_toolpath",
    "render_krl",
    "summarize",
    "write_krl",
]
