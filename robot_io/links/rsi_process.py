"""The RSI server in its own process, out of reach of the caller's GIL.

A CPython thread waits for the GIL for up to ``sys.getswitchinterval()`` (5 ms by default) while
another thread of its process computes; an RSI reply is due within 4 ms. :class:`RsiProcessServer`
runs :class:`~robot_io.links.rsi.RsiServer` in a child process (``spawn``) and talks to it through shared
memory: ``set_override`` writes one shared integer the server reads for every reply,
``set_correction`` sends the values over the pipe (the child hands them to its server at once:
no message is lost or doubled, so ``#RELATIVE`` increments add up as in-process), and the child
copies its counters, the controller's state and the correction sent into a shared block every
:data:`SYNC_PERIOD_S`. The interface is :class:`~robot_io.links.base.RobotLink`, as for the
in-process server; :attr:`stats`, :meth:`read_override` and :attr:`connected` lag the server by at
most one sync period. ``benchmarks/link_latency.py`` measures both against a CPU-bound thread.

Every way the child can fail to start — the port cannot be bound, a bad option, an interpreter
that dies before it reports (a broken environment), a child that cannot be spawned or does not
answer within :data:`_START_TIMEOUT_S` — is a :class:`~robot_io.links.base.LinkError` from the
constructor, with the child's exit code when it has one.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import os
import pickle
import threading
import time
from collections.abc import Sequence
from multiprocessing import spawn
from typing import Any

from robot_io.links.base import LinkError, LinkStats, LinkStatus, override_to_int
from robot_io.links.rsi import RobTelegram, RsiServer, correction_values
from robot_io.links.rsi_config import RsiConfig, load_rsi_config

__all__ = ["SYNC_PERIOD_S", "RsiProcessServer"]

#: How often the child copies the server's counters into shared memory [s].
SYNC_PERIOD_S = 0.005
#: How long the child may take to start (spawn re-imports the package) [s].
_START_TIMEOUT_S = 60.0
_FIELDS = ("sent", "replies", "malformed", "late", "timeouts", "reconnects", "short_first_dropped",
           "missed_cycles", "last_rx", "up", "ov_pro", "foreign_dropped", "cycle_ms")
_IDX = {name: i for i, name in enumerate(_FIELDS)}
_ERR_BYTES = 256
#: Room for the correction values the child reports (RKorr and AKorr have 6).
_CORR_SLOTS = 12


class _SharedOverrideServer(RsiServer):
    """RsiServer whose override lives in a shared integer (-1: none set yet)."""

    def __init__(self, cell: Any, **kwargs: Any) -> None:
        self._cell = cell  # before super().__init__ starts the server thread
        super().__init__(**kwargs)

    def _wanted_override(self) -> int | None:
        v = int(self._cell.value)
        return None if v < 0 else v


def _child(kwargs: dict, cell: Any, block: Any, err: Any, pipe: Any, corr: Any) -> None:
    """Child process: serve until the parent says stop or goes away."""
    try:
        srv = _SharedOverrideServer(cell, **kwargs)
    except LinkError as e:
        pipe.send(("error", str(e)))
        return
    except Exception as e:  # noqa: BLE001 - any failure to start is reported, not a dead pipe
        pipe.send(("error", f"RSI server could not start: {type(e).__name__}: {e}"))
        return
    pipe.send(("address", srv.address))
    try:
        while True:
            st = srv.stats
            last = srv.last_telegram
            values = (st.sent, st.replies, st.malformed, st.late, st.timeouts, st.reconnects,
                      srv.short_first_dropped, srv.missed_cycles, srv.last_receive_time, float(srv.connected),
                      math.nan if last is None or last.override is None else last.override,
                      srv.foreign_dropped, math.nan if srv.cycle_ms is None else srv.cycle_ms)
            for i, v in enumerate(values):
                block[i] = v
            for i, v in enumerate(srv.correction_sent[:_CORR_SLOTS]):
                corr[i] = v
            msg = st.last_error.encode("ascii", "replace")[:_ERR_BYTES - 1]
            err.value = msg
            if pipe.poll(SYNC_PERIOD_S):
                cmd = pipe.recv()
                if cmd == "stop":
                    break
                if isinstance(cmd, tuple) and cmd[0] == "correction":
                    srv.set_correction(cmd[1], cmd[2])  # checked by the parent; no answer
                    continue
                if cmd == "times":
                    pipe.send(srv.reply_times())
                elif cmd == "telegram":
                    pipe.send(srv.last_telegram)
    except (EOFError, OSError):  # the parent went away
        pass
    finally:
        srv.close()


class RsiProcessServer:
    """:class:`~robot_io.links.rsi.RsiServer` in a child process (implements
    :class:`~robot_io.links.base.RobotLink`).

    Args:
        bind_host, port, and any keyword of :class:`~robot_io.links.rsi.RsiServer` (``config``,
        ``controller``, ``reply_budget_s``, ``link_timeout_s``, ...); a ``config`` path is read here,
        in the caller's process, so a bad file fails before the child is spawned.

    Starting takes about a second (the child imports the package); construction raises
    :class:`~robot_io.links.base.LinkError` for every start failure (see the module docstring).
    """

    def __init__(self, bind_host: str = "127.0.0.1", port: int = 0, **kwargs: Any) -> None:
        self._closed = True  # until the child has started
        config = kwargs.get("config")
        if config is not None and not isinstance(config, RsiConfig):
            kwargs["config"] = load_rsi_config(config)  # errors here, in the caller's process
        cfg = kwargs.get("config")
        self.override_tag = (cfg.override_tag if isinstance(cfg, RsiConfig)
                             else kwargs.get("override_tag", "OvProW"))
        ctx = mp.get_context("spawn")
        self.link_timeout_s = float(kwargs.get("link_timeout_s", 0.25))
        self._cell = ctx.RawValue("i", -1)
        self._block = ctx.RawArray("d", len(_FIELDS))
        self._block[_IDX["ov_pro"]] = math.nan
        self._block[_IDX["last_rx"]] = -math.inf
        self._block[_IDX["cycle_ms"]] = math.nan
        self._err = ctx.RawArray("c", _ERR_BYTES)
        self._corr = ctx.RawArray("d", _CORR_SLOTS)
        try:
            shape = cfg if isinstance(cfg, RsiConfig) else RsiConfig.from_options(
                kwargs.get("sentype", "ImFree"), kwargs.get("override_tag", "OvProW"),
                kwargs.get("correction", "RKorr"))
            self.correction = shape.correction
            self._corr_tags = tuple(shape.correction_tags) if shape.correction is not None else ()
        except (LinkError, ValueError, TypeError):  # a bad option: the child's server says which
            self.correction, self._corr_tags = None, ()
        self._pipe, child_end = ctx.Pipe()
        self._pipe_lock = threading.Lock()
        kwargs.update(bind_host=bind_host, port=port)
        self._proc = ctx.Process(target=_child,
                                 args=(kwargs, self._cell, self._block, self._err, child_end, self._corr),
                                 name=f"rsi-server-{port}", daemon=True)
        try:
            self._proc.start()
        except (OSError, pickle.PicklingError, TypeError, AttributeError) as e:
            child_end.close()
            self._pipe.close()
            self._kill()
            raise LinkError("rsi", f"cannot start the RSI server process: {type(e).__name__}: {e}") from e
        child_end.close()
        try:
            if not self._pipe.poll(_START_TIMEOUT_S):
                self._kill()
                self._pipe.close()
                raise LinkError("rsi", f"RSI server process did not start within {_START_TIMEOUT_S:.0f} s")
            kind, value = self._pipe.recv()
        except (EOFError, OSError) as e:  # the child died before it reported
            self._proc.join(5.0)
            self._kill()
            self._pipe.close()
            raise LinkError("rsi", f"RSI server process exited (exit code {self._proc.exitcode}) before it "
                                   "started: the child re-imports robot_io and the caller's main module in a "
                                   f"fresh interpreter; check that {os.fsdecode(spawn.get_executable())} can "
                                   "import them (a script needs an `if __name__ == \"__main__\":` guard)"
                                   ) from e
        if kind == "error":
            self._proc.join(5.0)
            self._pipe.close()
            raise LinkError("rsi", value.removeprefix("rsi: "))
        self.address: tuple[str, int] = tuple(value)  # type: ignore[assignment]
        self._closed = False

    def _get(self, name: str) -> float:
        return self._block[_IDX[name]]

    # -- RobotLink -------------------------------------------------------------------------------
    def set_override(self, percent: float) -> LinkStatus:
        value = override_to_int(percent)
        if value is None:
            return LinkStatus(False, f"override {percent!r} is not a finite number; nothing sent")
        if self._closed:
            return LinkStatus(False, "link closed")
        if self.override_tag is None:
            return LinkStatus(False, "the RSI configuration has no override channel (a RECEIVE element "
                                     "OvProW wired to MAP2OV_PRO); nothing is sent")
        self._cell.value = value
        if self.connected:
            return LinkStatus(True, "sent in next reply", value)
        return LinkStatus(False, f"no <Rob> from the controller for {self.link_timeout_s:g} s; value kept "
                                 "for the next reply", value)

    def set_correction(self, values: Sequence[float], mode: str = "relative") -> LinkStatus:
        """As :meth:`robot_io.links.rsi.RsiServer.set_correction` (checked here, applied by the
        child's server on receipt; ``percent`` 0: taken, ``None``: not)."""
        tags = self._corr_tags
        if self._closed:
            return LinkStatus(False, "link closed")
        vals = correction_values(values, mode, self.correction, tags)
        if isinstance(vals, LinkStatus):
            return vals
        try:
            with self._pipe_lock:
                self._pipe.send(("correction", vals, mode))
        except (OSError, ValueError) as e:
            return LinkStatus(False, f"RSI server process does not take it: {type(e).__name__}: {e}")
        up = self.connected
        return LinkStatus(up, "sent in next reply" if up
                          else "no <Rob> from the controller; kept for the next reply", 0)

    @property
    def correction_sent(self) -> tuple[float, ...]:
        """As :attr:`robot_io.links.rsi.RsiServer.correction_sent`, at most one sync period old."""
        return tuple(self._corr[i] for i in range(min(len(self._corr_tags), _CORR_SLOTS)))

    def read_override(self) -> float | None:
        v = self._get("ov_pro")
        return None if math.isnan(v) else v

    @property
    def stats(self) -> LinkStats:
        b = self._block
        err = bytes(self._err.value).decode("ascii", "replace")
        return LinkStats(sent=int(b[_IDX["sent"]]), replies=int(b[_IDX["replies"]]),
                         malformed=int(b[_IDX["malformed"]]), late=int(b[_IDX["late"]]),
                         timeouts=int(b[_IDX["timeouts"]]), reconnects=int(b[_IDX["reconnects"]]),
                         last_error=err)

    @property
    def connected(self) -> bool:
        return bool(self._get("up")) and time.monotonic() - self._get("last_rx") < self.link_timeout_s

    def close(self) -> None:
        if getattr(self, "_closed", True):
            return
        self._closed = True
        try:
            with self._pipe_lock:
                self._pipe.send("stop")
        except OSError:
            pass
        self._proc.join(5.0)
        self._kill()
        self._pipe.close()

    def __enter__(self) -> RsiProcessServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- extras ------------------------------------------------------------------------------------
    @property
    def short_first_dropped(self) -> int:
        return int(self._get("short_first_dropped"))

    @property
    def missed_cycles(self) -> int:
        return int(self._get("missed_cycles"))

    @property
    def foreign_dropped(self) -> int:
        """Datagrams from other senders than the controller, dropped unparsed."""
        return int(self._get("foreign_dropped"))

    @property
    def cycle_ms(self) -> int | None:
        """The controller's IPOC step per cycle [ms] learned from the sequence, ``None`` before."""
        v = self._get("cycle_ms")
        return None if math.isnan(v) else int(v)

    def _ask(self, cmd: str) -> Any:
        with self._pipe_lock:
            self._pipe.send(cmd)
            if not self._pipe.poll(5.0):
                raise LinkError("rsi", "RSI server process does not answer")
            return self._pipe.recv()

    def reply_times(self) -> list[float]:
        """The server's receive-to-reply times [s] (see :meth:`robot_io.links.rsi.RsiServer.reply_times`)."""
        return self._ask("times")

    @property
    def last_telegram(self) -> RobTelegram | None:
        return self._ask("telegram")

    def _kill(self) -> None:
        if self._proc.is_alive():
            self._proc.terminate()
            self._proc.join(5.0)
