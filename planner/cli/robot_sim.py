"""``cctmill robot-sim kvp|rsi --port N``: run a simulated controller on its own.

- ``kvp``: a simulated KukaVarProxy server listening on ``--host:--port`` (the supervisor, or any
  OpenShowVar client, connects to it and writes ``$OV_PRO``);
- ``rsi``: a simulated KR C4 sending RSI ``<Rob>`` telegrams every ``--cycle-ms`` to the PC's RSI
  server at ``--host:--port`` (the controller is the RSI client).

Both apply the override to a simulated path speed and print their counters every
``--stats-every-s`` until Ctrl-C or ``--duration-s``. Exit status 0, or 1 when the RSI controller
stopped by itself (``RSIBad``: too many late replies).
"""

from __future__ import annotations

import argparse
import time

from models.errors import InputError
from robot_io.links.kvp_sim import KvpSimServer
from robot_io.links.rsi_config import load_rsi_config
from robot_io.links.rsi_sim import RsiSimController

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``robot-sim`` subcommand."""
    p = sub.add_parser("robot-sim", help="run a simulated KUKA controller (KukaVarProxy server or RSI "
                                         "controller) until Ctrl-C")
    p.add_argument("kind", choices=["kvp", "rsi"],
                   help="kvp: KukaVarProxy server to connect to; rsi: controller sending to a PC server")
    p.add_argument("--port", type=int, required=True,
                   help="kvp: TCP port to listen on (0 = any free one, printed); rsi: UDP port of the PC's "
                        "RSI server to send to")
    p.add_argument("--host", default="127.0.0.1",
                   help="kvp: address to bind; rsi: address of the PC server (default 127.0.0.1)")
    p.add_argument("--count-trailer", action=argparse.BooleanOptionalAction, default=True,
                   help="kvp: reply body_len counts the 3 trailer bytes (KUKAVARPROXY source; default) or "
                        "not (--no-count-trailer, the server of the py_openshowvar README)")
    p.add_argument("--cycle-ms", type=int, choices=[4, 12], default=4,
                   help="rsi: cycle, 4 (KR C4 #IPO_FAST, default) or 12 (#IPO / KR C2)")
    p.add_argument("--timeout-packets", type=int, default=100,
                   help="rsi: consecutive late replies before RSIBad (default 100)")
    p.add_argument("--rsi-config", metavar="ETHERNET.xml",
                   help="rsi: the controller's RSI ETHERNET configuration (SENTYPE checked in replies, "
                        "override channel and read-back tags; see docs/links.md)")
    p.add_argument("--programmed-speed-mm-s", type=float, default=1.0,
                   help="programmed path speed $VEL.CP of the simulated motion [mm/s] (default 1)")
    p.add_argument("--duration-s", type=float, default=None, help="stop after this long [s]")
    p.add_argument("--stats-every-s", type=float, default=1.0, help="print counters this often [s]")
    p.set_defaults(run=run)


def _check(args: argparse.Namespace) -> None:
    if not 0 <= args.port <= 65535 or (args.kind == "rsi" and args.port == 0):
        raise InputError("--port", f"{args.port} is not a port (kvp: 0..65535, rsi: 1..65535)")
    if args.duration_s is not None and not args.duration_s > 0:
        raise InputError("--duration-s", "must be positive")
    if not args.stats_every_s > 0:
        raise InputError("--stats-every-s", "must be positive")
    if not args.programmed_speed_mm_s >= 0:
        raise InputError("--programmed-speed-mm-s", "must be non-negative")
    if args.timeout_packets < 1:
        raise InputError("--timeout-packets", "must be at least 1")


def _kvp_line(t: float, srv: KvpSimServer) -> str:
    s = srv.stats
    return (f"t={t:7.1f} s  clients {srv.client_count}  requests {s.requests}  replies {s.replies}  "
            f"malformed {s.malformed}  $OV_PRO {srv.override_percent:.0f}  "
            f"path speed {srv.path_speed() * 1e3:.3f} mm/s")


def _rsi_line(t: float, sim: RsiSimController) -> str:
    s = sim.stats
    return (f"t={t:7.1f} s  {sim.status}  cycles {s.cycles}  replies {s.replies}  late {s.late}  "
            f"stale {s.stale}  wrong-IPOC {s.wrong_ipoc}  malformed {s.malformed}  "
            f"$OV_PRO {sim.override_percent:.0f}  path speed {sim.path_speed() * 1e3:.3f} mm/s")


def _line(t: float, peer: KvpSimServer | RsiSimController) -> str:
    return _kvp_line(t, peer) if isinstance(peer, KvpSimServer) else _rsi_line(t, peer)


def run(args: argparse.Namespace) -> int:
    """Run the simulated controller; 0 on Ctrl-C or at ``--duration-s``, 1 after RSIBad."""
    _check(args)
    speed = args.programmed_speed_mm_s * 1e-3
    peer: KvpSimServer | RsiSimController
    if args.kind == "kvp":
        server = KvpSimServer(args.host, args.port, args.count_trailer, programmed_speed=speed)
        peer = server.start()
        host, port = server.address
        print(f"simulated KukaVarProxy listening on {host}:{port} (body_len "
              f"{'counts' if args.count_trailer else 'excludes'} the trailer); Ctrl-C to stop", flush=True)
    else:
        config = load_rsi_config(args.rsi_config) if args.rsi_config else None
        peer = RsiSimController((args.host, args.port), cycle_s=args.cycle_ms * 1e-3,
                                timeout_packets=args.timeout_packets, programmed_speed=speed, config=config)
        peer.start()
        print(f"simulated RSI controller sending <Rob> every {args.cycle_ms} ms to {args.host}:{args.port}"
              f" (RSIBad after {args.timeout_packets} late replies); Ctrl-C to stop", flush=True)
    t0 = time.monotonic()
    status = 0
    try:
        next_print = t0 + args.stats_every_s
        while True:
            now = time.monotonic()
            if args.duration_s is not None and now - t0 >= args.duration_s:
                break
            if isinstance(peer, RsiSimController) and peer.status == "RSIBad":
                status = 1
                break
            if now >= next_print:
                print(_line(now - t0, peer), flush=True)
                next_print += args.stats_every_s
            time.sleep(min(0.05, args.stats_every_s))
    except KeyboardInterrupt:
        pass
    finally:
        peer.stop()
    print(_line(time.monotonic() - t0, peer), flush=True)
    if status:
        print(f"RSIBad: {args.timeout_packets} consecutive replies missed the {args.cycle_ms} ms cycle; "
              "is the PC's RSI server running on that port?", flush=True)
    return status
