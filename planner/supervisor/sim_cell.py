"""A whole simulated cell on loopback: controller, link, DAQ stream and the cut.

- controller: the simulated KukaVarProxy server (:class:`robot_io.links.kvp_sim.KvpSimServer`, with the
  supervisor's :class:`robot_io.links.kvp.KvpClient` as link) or the simulated RSI controller
  (:class:`robot_io.links.rsi_sim.RsiSimController`, sending ``<Rob>`` every cycle to the supervisor's
  :class:`robot_io.links.rsi.RsiServer`);
- signal: :class:`planner.supervisor.sim_cut.SimulatedCut` whose feed follows the override the *controller*
  applies, its samples sent as UDP datagrams (:mod:`robot_io.signals.udp`) by :meth:`SimCell.daq`
  and received by a :class:`robot_io.signals.udp.UdpSignalSource`.

Every socket is real and bound to 127.0.0.1. Used by ``cctmill supervise --signal sim --robot
sim`` and by the end-to-end tests; :meth:`restart_controller` cuts the controller link and brings
it back on the same port (the link-loss test).
"""

from __future__ import annotations

import time

from models.errors import InputError
from planner.plan_file import Plan
from planner.supervisor.sim_cut import CutScenario, SimulatedCut
from robot_io.links.kvp import KvpClient
from robot_io.links.kvp_sim import KvpSimServer
from robot_io.links.rsi import RsiServer
from robot_io.links.rsi_sim import RsiSimController
from robot_io.signals.udp import UdpSignalSender, UdpSignalSource

__all__ = ["ROBOTS", "SimCell"]

#: Simulated controllers.
ROBOTS = ("kvp", "rsi")


class SimCell:
    """Controller sim + link + UDP signal path + simulated cut (a context manager).

    Args:
        plan: the plan being cut.
        robot: ``"kvp"`` or ``"rsi"``.
        fs_hz: signal sample rate [Hz].
        scenario: the simulated cut.
        cycle_s: RSI cycle [s] (0.004 or 0.012).
        kvp_timeout_s: KvpClient reply timeout [s].
        start_s: arc length where the simulated cut starts [m].
    """

    def __init__(self, plan: Plan, robot: str = "kvp", fs_hz: float = 10_000.0,
                 scenario: CutScenario | None = None, cycle_s: float = 0.004,
                 kvp_timeout_s: float = 0.5, start_s: float = 0.0) -> None:
        if robot not in ROBOTS:
            raise InputError("sim_protocol", f"{robot!r}: use one of {', '.join(ROBOTS)}")
        self.robot = robot
        self.fs_hz = fs_hz
        self.cycle_s = cycle_s
        self.kvp_server: KvpSimServer | None = None
        self.rsi_controller: RsiSimController | None = None
        self.link: KvpClient | RsiServer
        if robot == "kvp":
            self.kvp_server = KvpSimServer().start()
            self.link = KvpClient(*self.kvp_server.address, timeout=kvp_timeout_s,
                                  backoff_initial_s=0.02, backoff_max_s=0.2)
        else:
            self.link = RsiServer(cycle_ms=int(round(cycle_s * 1000)))
            self.rsi_controller = RsiSimController(self.link.address, cycle_s=cycle_s).start()
        self.source = UdpSignalSource()
        self._sender = UdpSignalSender(*self.source.address)
        self.cut = SimulatedCut(plan, self.applied_override, fs_hz, scenario, start_s=start_s)

    def applied_override(self) -> float:
        """The override the simulated controller applies now [percent]."""
        if self.kvp_server is not None:
            return self.kvp_server.override_percent
        if self.rsi_controller is not None:
            return self.rsi_controller.override_percent
        return 100.0

    def daq(self, now: float | None = None) -> None:
        """Generate the samples due by now and send them over UDP (the loop's ``before_step``)."""
        t, y = self.cut.generate()
        if y.size:
            self._sender.send(float(t[0]), self.fs_hz, y)

    def stop_controller(self) -> None:
        """Take the controller away (server closed / controller stopped)."""
        if self.kvp_server is not None:
            self.kvp_server.stop()
        if self.rsi_controller is not None:
            self.rsi_controller.stop()

    def start_controller(self) -> None:
        """Bring the controller back on the same address, with the override it had (``$OV_PRO``
        belongs to the controller, not to the proxy or the RSI context)."""
        if self.kvp_server is not None:
            port = self.kvp_server.port
            # the controller keeps its $OV_PRO while the proxy is away
            variables = dict(self.kvp_server.variables)
            deadline = time.monotonic() + 2.0
            while True:
                try:
                    self.kvp_server = KvpSimServer(port=port, variables=variables).start()
                    return
                except Exception:  # noqa: BLE001 - port still in TIME_WAIT on a slow machine
                    if time.monotonic() > deadline:
                        raise
                    time.sleep(0.02)
        elif isinstance(self.link, RsiServer):
            last = self.rsi_controller.override_percent if self.rsi_controller is not None else 100.0
            self.rsi_controller = RsiSimController(self.link.address, cycle_s=self.cycle_s,
                                                   override_percent=last).start()

    def close(self) -> None:
        self.link.close()
        self.stop_controller()
        self.source.close()
        self._sender.close()

    def __enter__(self) -> SimCell:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
