"""Throughput of the point model: CCT stiffness + γ + stability margin, poses per second.

What is measured
    The kernel is ``point_function(robot, "thesis", "isotropic", outputs=("stiffness", "gamma",
    "margin"))``: for one pose and one cut it computes the average cutting force, the CCT
    translational stiffness K_t under that force, the 2-DOF frame, γ and the stability margin
    (docs/model.md §3–§5). It is evaluated on ``--n`` (default 100,000) random reachable poses of the
    KR 210, each with the thesis's Case 1 cut (up milling, a_e 15.24 mm, a_p 5.08 mm, two flutes,
    R 12.7 mm, 1000 rpm, 1 mm/s).

Poses
    Joint values uniform inside the joint limits (seeded), rejecting singular poses with the test
    of :meth:`models.point.PointModel.check_pose` (σ_min of the linear TCP Jacobian, and of the full
    Jacobian with its angular rows scaled by ``JACOBIAN_LENGTH``, both ≥ ``JACOBIAN_SIGMA_MIN``),
    vectorised. "Reachable" = inside the limits and not singular.

Cut frame
    Derived per pose from its tool axis, so that the cut is physically consistent (docs/model.md §4: Y_o
    should be the tool axis): Y_o = tool axis (TCP +x), Z_o (feed) = base +Y projected onto the
    plane normal to the tool axis (base +X when the tool axis is within 26° of base Y),
    X_o = Y_o × Z_o. So the ``cut`` input is mapped (12 × n), as along a real path.

Variants (same process, same poses)
    baseline  straightforward per-pose numpy/pinocchio: pinocchio frame Jacobian
              (LOCAL_WORLD_ALIGNED at the TCP frame) and kinematic Hessian for K_c, numpy solves,
              closed-form average force and cutting stiffness, eigh/eigvals for the 2×2 problem.
              Timed on a subset (``--baseline-n``) and checked against the kernel on that subset.
    casadi VM serial/thread  ``f.map(n)`` and ``f.map(n, "thread", 2)``, called from Python the
              ordinary way (numpy in, DM out, converted to numpy), and through CasADi's zero-copy
              buffer interface (``Function.buffer``: numpy memory in and out, no conversion).
    compiled C  the kernel code-generated (``CodeGenerator``, with CasADi's common-subexpression
              elimination), compiled with gcc, loaded with ``ca.external`` and mapped the same ways.
              ``-ffast-math`` is tried too and reported only if it agrees with the VM to tolerance.

Every variant's outputs are checked against the serial VM map's before its rate is reported;
the baseline is checked against the kernel on its subset and the script fails loudly if not.
Rates are best of three repeats; the worst is reported too.

Run from the repository root: ``python benchmarks/throughput.py [--n N] [--baseline-n M] [--json]``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import casadi as ca  # noqa: E402
import pinocchio as pin  # noqa: E402

from models import Cut, ModelParameters, load_material, load_robot, point_function  # noqa: E402
from models.analysis import CUT_LAYOUT, PARAM_LAYOUT  # noqa: E402
from models.point import JACOBIAN_LENGTH, JACOBIAN_SIGMA_MIN  # noqa: E402
from models.robot import Robot  # noqa: E402

BUILD_DIR = Path(__file__).resolve().parent / "_build"
SEED = 20_210_417
OUTPUTS = ("stiffness", "gamma", "margin")

#: Targets of the issue: poses per second on this (2-core) machine, and speed-up over the baseline.
TARGET_RATE = 500_000.0
TARGET_RATIO = 50.0
#: The thesis enumerated this many poses for one table.
THESIS_POSES = 1e8
REPEATS = 3

#: Agreement tolerances (kernel vs baseline, and every variant vs the serial VM map).
#: K_t: Frobenius-norm relative error [-]; a few hundred ulps of the conditioning of C_tt⁻¹.
KT_REL_TOL = 1e-8
#: γ: absolute error [rad], taken modulo π (γ is an angle between undirected lines).
GAMMA_ABS_TOL = 1e-9
#: margin: relative error [-] w.r.t. max(|margin|, MARGIN_SCALE_REL · K_max). The margin is a
#: difference of eigenvalues of A whose entries are O(K_max); where it crosses zero only an error
#: relative to that scale is meaningful.
MARGIN_REL_TOL = 1e-8
MARGIN_SCALE_REL = 1e-6

#: Case 1 of the thesis (docs/model.md §4), in SI.
CASE1 = {"a_e": 15.24e-3, "a_p": 5.08e-3, "mode": "up", "spindle_speed": 1000 * 2 * np.pi / 60,
         "flutes": 2, "radius": 12.7e-3}
CASE1_FEED = 1e-3  # [m/s]

#: Tool axes closer to base Y than this cosine take base X as the feed reference instead [-].
_FEED_REF_SWITCH = 0.9

GCC_FLAGS = ("-O3", "-march=native")
GCC_FAST_MATH = "-ffast-math"


# ----------------------------------------------------------------------------------- the setup
@dataclass
class Problem:
    """Poses, per-pose cuts and parameters, as contiguous numpy arrays (row k = pose k)."""

    q: np.ndarray        # (n, 6) [rad]
    cut: np.ndarray      # (n, 12) CUT_LAYOUT
    feed: np.ndarray     # (1,) [m/s]
    params: np.ndarray   # (23,) PARAM_LAYOUT
    drawn: int           # random poses drawn to get n reachable ones
    sigma_lin_min: float  # smallest σ_min(J_v) among the kept poses [m/rad]


def _geometry_function(robot: Robot) -> ca.Function:
    s = robot.symbolic
    return ca.Function("geometry", [s.q, s.tcp], [s.jacobian, s.rotation[:, 0]],
                       ["q", "tcp"], ["J", "tool_axis"])


def cut_frames(tool_axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Feed Z_o and radial X_o [unit, base axes], shape (n, 3) each, with Y_o = the tool axis.

    Z_o is base +Y projected normal to the tool axis (base +X if the axis is near base Y).
    """
    t = tool_axis / np.linalg.norm(tool_axis, axis=1, keepdims=True)
    ref = np.zeros_like(t)
    near_y = np.abs(t[:, 1]) > _FEED_REF_SWITCH
    ref[~near_y, 1] = 1.0
    ref[near_y, 0] = 1.0
    z = ref - np.sum(ref * t, axis=1, keepdims=True) * t
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    x = np.cross(t, z)  # X_o = Y_o × Z_o, so that Z_o × X_o = Y_o
    return z, x


def reachable_poses(robot: Robot, n: int, seed: int, tcp: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, int, float]:
    """``n`` random poses inside the joint limits and not singular (PointModel.check_pose's test).

    Returns (q (n, 6) [rad], tool axis (n, 3), number drawn, smallest kept σ_min(J_v) [m/rad]).
    """
    rng = np.random.default_rng(seed)
    lo, hi = robot.data.lower, robot.data.upper
    geo = _geometry_function(robot)
    kept_q, kept_axis, kept_sigma = [], [], []
    have = drawn = 0
    while have < n:
        m = int(1.2 * (n - have)) + 16
        q = rng.uniform(lo, hi, size=(m, robot.nq))
        drawn += m
        jac, axis = geo.map(m)(q.T, tcp)
        jac = np.asarray(jac).reshape(6, m, robot.nq).transpose(1, 0, 2)
        axis = np.asarray(axis).T
        sigma_lin = np.linalg.svd(jac[:, 0:3, :], compute_uv=False)[:, -1]
        scaled = jac.copy()
        scaled[:, 3:6, :] *= JACOBIAN_LENGTH
        sigma_all = np.linalg.svd(scaled, compute_uv=False)[:, -1]
        ok = (sigma_lin >= JACOBIAN_SIGMA_MIN) & (sigma_all >= JACOBIAN_SIGMA_MIN)
        kept_q.append(q[ok])
        kept_axis.append(axis[ok])
        kept_sigma.append(sigma_lin[ok])
        have += int(ok.sum())
    q = np.concatenate(kept_q)[:n]
    axis = np.concatenate(kept_axis)[:n]
    sigma = np.concatenate(kept_sigma)[:n]
    return np.ascontiguousarray(q), axis, drawn, float(sigma.min())


def make_problem(robot: Robot, n: int, seed: int = SEED) -> Problem:
    params = ModelParameters(joint_stiffness=robot.data.joint_stiffness,
                             coefficients=load_material("al6061").coefficients())
    q, axis, drawn, sigma = reachable_poses(robot, n, seed, params.tcp)
    template = Cut(feed_dir=[0, 1, 0], radial_dir=[1, 0, 0], **CASE1).vector()
    cut = np.tile(template, (n, 1))
    z, x = cut_frames(axis)
    (oz, _), (ox, _) = CUT_LAYOUT["feed_dir"], CUT_LAYOUT["radial_dir"]
    cut[:, oz:oz + 3] = z
    cut[:, ox:ox + 3] = x
    return Problem(q=q, cut=np.ascontiguousarray(cut), feed=np.array([CASE1_FEED]),
                   params=params.vector(), drawn=drawn, sigma_lin_min=sigma)


# ----------------------------------------------------------------------- the per-pose baseline
def _part(vec: np.ndarray, layout: dict[str, tuple[int, int]], name: str) -> np.ndarray:
    offset, size = layout[name]
    return vec[offset:offset + size]


_LEVI_CIVITA = np.zeros((3, 3, 3))
_LEVI_CIVITA[0, 1, 2] = _LEVI_CIVITA[1, 2, 0] = _LEVI_CIVITA[2, 0, 1] = 1.0
_LEVI_CIVITA[0, 2, 1] = _LEVI_CIVITA[2, 1, 0] = _LEVI_CIVITA[1, 0, 2] = -1.0

class Baseline:
    """Straightforward per-pose numpy/pinocchio implementation of the same three outputs.

    No vectorisation and no CasADi: what a competent engineer writes first. Closed forms of
    docs/model.md §4 for the average force and the cutting stiffness (derivatives by hand), pinocchio for
    the Jacobian and its derivative, numpy for the rest (docs/model.md §3, §5).
    """

    def __init__(self, robot: Robot, tcp: np.ndarray) -> None:
        self.model, self.tcp_frame = robot.pin_model(tcp=tcp)
        self.data = self.model.createData()
        self.joint = self.model.frames[self.tcp_frame].parentJoint

    @staticmethod
    def _brackets(phi: float, c: float, k: np.ndarray) -> np.ndarray:
        k_tc, k_rc, k_ac, k_te, k_re, k_ae = k
        sweep = 2 * phi - math.sin(2 * phi)
        return np.array([
            c * (k_tc * sweep + k_rc * math.cos(2 * phi))
            - 4 * (k_te * math.cos(phi) + k_re * math.sin(phi)),
            4 * (-c * k_ac * math.cos(phi) + k_ae * phi),  # ×4: the y bracket has N a/2π
            c * (k_tc * math.cos(2 * phi) - k_rc * sweep)
            - 4 * (k_te * math.sin(phi) - k_re * math.cos(phi)),
        ])

    @staticmethod
    def _bracket_slopes(phi: float, c: float, k: np.ndarray) -> np.ndarray:
        """d/dφ of :meth:`_brackets`."""
        k_tc, k_rc, k_ac, k_te, k_re, k_ae = k
        return np.array([
            c * (k_tc * (2 - 2 * math.cos(2 * phi)) - 2 * k_rc * math.sin(2 * phi))
            + 4 * (k_te * math.sin(phi) - k_re * math.cos(phi)),
            4 * (c * k_ac * math.sin(phi) + k_ae),
            c * (-2 * k_tc * math.sin(2 * phi) - k_rc * (2 - 2 * math.cos(2 * phi)))
            - 4 * (k_te * math.cos(phi) + k_re * math.sin(phi)),
        ])

    def cutting(self, cut: np.ndarray, feed: float, coeffs: np.ndarray):
        """(F_o (3,) [N], K_px, K_py [N/m]) of the cut vector, closed forms (docs/model.md §4)."""
        a_e, a_p, omega, flutes, radius = (
            _part(cut, CUT_LAYOUT, k)[0] for k in ("a_e", "a_p", "spindle_speed", "flutes", "radius"))
        mode = int(round(_part(cut, CUT_LAYOUT, "mode")[0]))
        c = feed / (flutes * omega / (2 * math.pi))
        arc = math.acos(1 - a_e / radius) if mode != 2 else math.pi
        phi_st, phi_ex = ((0.0, arc) if mode == 0 else
                          (math.pi - arc, math.pi) if mode == 1 else (0.0, math.pi))
        scale = flutes * a_p / (8 * math.pi)
        force = scale * (self._brackets(phi_ex, c, coeffs) - self._brackets(phi_st, c, coeffs))
        if mode == 0:    # dφ_ex/da_e = 1/(R sin φ_ex)
            d_force = scale * self._bracket_slopes(phi_ex, c, coeffs) / (radius * math.sin(arc))
        elif mode == 1:  # dφ_st/da_e = −1/(R sin φ_st)
            d_force = scale * self._bracket_slopes(phi_st, c, coeffs) / (radius * math.sin(arc))
        else:
            d_force = np.zeros(3)
        k_pxo = float(np.linalg.norm(d_force))
        k_pyo = -float(np.linalg.norm(force)) / a_p
        alpha = math.atan2(force[2], force[0])
        return force, k_pxo * math.cos(alpha), k_pyo

    def point(self, q: np.ndarray, cut: np.ndarray, feed: float, params: np.ndarray):
        """(K_t (3, 3) [N/m], γ [rad], margin [N/m]) of one pose."""
        model, data = self.model, self.data
        k_theta = _part(params, PARAM_LAYOUT, "joint_stiffness")
        cct = _part(params, PARAM_LAYOUT, "cct")[0]
        coeffs = _part(params, PARAM_LAYOUT, "coefficients")
        gain = _part(params, PARAM_LAYOUT, "process_gain")[0]
        z_o = _part(cut, CUT_LAYOUT, "feed_dir")
        x_o = _part(cut, CUT_LAYOUT, "radial_dir")
        z_o = z_o / np.linalg.norm(z_o)
        x_o = x_o / np.linalg.norm(x_o)
        y_o = np.array([z_o[1] * x_o[2] - z_o[2] * x_o[1], z_o[2] * x_o[0] - z_o[0] * x_o[2],
                        z_o[0] * x_o[1] - z_o[1] * x_o[0]])
        f_o, k_px, k_py = self.cutting(cut, feed, coeffs)
        f_base = f_o[0] * x_o + f_o[1] * y_o + f_o[2] * z_o

        # Jacobian at the TCP and its derivative (docs/model.md §3).
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        jac = pin.getFrameJacobian(model, data, self.tcp_frame, pin.LOCAL_WORLD_ALIGNED)
        pin.computeJointKinematicHessians(model, data, q)
        # pinocchio 4.1's Python binding returns the axes reversed (docs/model.md §3): transpose.
        hess = pin.getJointKinematicHessian(model, data, self.joint,
                                            pin.LOCAL_WORLD_ALIGNED).transpose(2, 1, 0)
        # hess[a, i, k] = ∂J_joint[a, i]/∂q_k at the joint origin; shift to the TCP:
        # J_v,tcp = J_v − [r]× J_w with r = p_tcp − p_joint, ∂r/∂q_k = J_w[:, k] × r.
        r = data.oMf[self.tcp_frame].translation - data.oMi[self.joint].translation
        j_w = jac[3:6, :]
        d_r = np.einsum("abc,bk,c->ka", _LEVI_CIVITA, j_w, r)  # row k: ∂r/∂q_k = J_w[:, k] × r
        d_jv = (hess[0:3] - np.einsum("abc,kb,ci->aik", _LEVI_CIVITA, d_r, j_w)
                - np.einsum("abc,b,cik->aik", _LEVI_CIVITA, r, hess[3:6]))
        # K_c[i, k] = Σ_a ∂J_v[a, i]/∂q_k f_a
        k_c = cct * np.einsum("aik,a->ik", d_jv, f_base)
        jv = jac[0:3, :]
        c_tt = jv @ np.linalg.solve(np.diag(k_theta) - k_c, jv.T)
        c_tt = 0.5 * (c_tt + c_tt.T)
        k_t = np.linalg.inv(c_tt)
        k_t = 0.5 * (k_t + k_t.T)

        # The 2-DOF problem in Δ (docs/model.md §5, thesis process model, isotropic mass).
        alpha = math.atan2(f_o[2], f_o[0])
        x_d = math.cos(alpha) * x_o + math.sin(alpha) * z_o
        plane = np.column_stack([x_d, y_o])
        k2 = plane.T @ k_t @ plane
        k2 = 0.5 * (k2 + k2.T)
        values, vectors = np.linalg.eigh(k2)  # ascending
        k_min, k_max = values
        v = np.column_stack([vectors[:, 1], vectors[:, 0]])
        theta = math.atan2(v[1, 0], v[0, 0])
        beta = math.atan2(f_o[1], math.hypot(f_o[0], f_o[2]))
        gamma = math.pi / 2 - (math.pi / 2 - (theta - beta)) % math.pi
        k_p = gain * np.outer([math.cos(beta), math.sin(beta)], [k_px, k_py])
        a = v.T @ k_p @ v - np.diag([k_max, k_min])
        lam = np.linalg.eigvals(a)
        if np.iscomplexobj(lam) and lam[0].imag != 0.0:
            margin = min(-lam[0].real, -abs(lam[0].imag))
        else:
            lo, hi = sorted(np.real(lam))
            margin = min(-hi, 0.5 * (hi - lo))
        return k_t, gamma, margin

    def run(self, prob: Problem, count: int):
        k_t = np.empty((count, 3, 3))
        gamma = np.empty(count)
        margin = np.empty(count)
        feed = float(prob.feed[0])
        for i in range(count):
            k_t[i], gamma[i], margin[i] = self.point(prob.q[i], prob.cut[i], feed, prob.params)
        return k_t, gamma, margin


# --------------------------------------------------------------------------------- agreement
@dataclass
class Agreement:
    kt_rel: float
    gamma_abs: float
    margin_rel: float

    @property
    def ok(self) -> bool:
        return (self.kt_rel < KT_REL_TOL and self.gamma_abs < GAMMA_ABS_TOL
                and self.margin_rel < MARGIN_REL_TOL)

    def text(self) -> str:
        return (f"K_t rel {self.kt_rel:.1e} (< {KT_REL_TOL:.0e}), γ abs {self.gamma_abs:.1e} rad "
                f"(< {GAMMA_ABS_TOL:.0e}), margin rel {self.margin_rel:.1e} "
                f"(< {MARGIN_REL_TOL:.0e})")


def compare(out, ref) -> Agreement:
    k, g, m = out
    k_ref, g_ref, m_ref = ref
    norm = np.linalg.norm(k_ref.reshape(len(k_ref), -1), axis=1)
    kt_rel = np.linalg.norm((k - k_ref).reshape(len(k), -1), axis=1) / norm
    dg = np.abs((g - g_ref + np.pi / 2) % np.pi - np.pi / 2)
    k_max = np.linalg.eigvalsh(k_ref)[:, -1]
    m_scale = np.maximum(np.abs(m_ref), MARGIN_SCALE_REL * k_max)
    m_rel = np.abs(m - m_ref) / m_scale
    if not (np.all(np.isfinite(k)) and np.all(np.isfinite(g)) and np.all(np.isfinite(m))):
        return Agreement(math.inf, math.inf, math.inf)
    return Agreement(float(kt_rel.max()), float(dg.max()), float(m_rel.max()))


# ---------------------------------------------------------------------------- kernel variants
class Runner:
    """Evaluate a mapped kernel on a :class:`Problem` and return (K_t, γ, margin) as numpy."""

    def __init__(self, kernel: ca.Function, prob: Problem, threads: int, zero_copy: bool) -> None:
        n = prob.q.shape[0]
        self.prob, self.n, self.zero_copy = prob, n, zero_copy
        self.k_t = np.empty((n, 3, 3))
        self.gamma = np.empty(n)
        self.margin = np.empty(n)
        if not zero_copy:
            self.fun = kernel.map(n) if threads == 1 else kernel.map(n, "thread", threads)
            return
        # q and cut mapped, feed and params shared (not repeated in memory).
        if threads == 1:
            fun = kernel.map("serial_map", "serial", n, [2, 3], [])
        else:
            inner = kernel.map("serial_chunk", "serial", n // threads, [2, 3], [])
            fun = inner.map("thread_map", "thread", threads, [2, 3], [])
        self.fun = fun
        self.buf, self.evaluate = fun.buffer()
        # Column-major CasADi (rows × n·cols) == C-order numpy (n, cols, rows).
        for i, arr in enumerate((prob.q, prob.cut, prob.feed, prob.params)):
            self.buf.set_arg(i, memoryview(arr))
        for i, arr in enumerate((self.k_t, self.gamma, self.margin)):
            self.buf.set_res(i, memoryview(arr))

    def __call__(self):
        if self.zero_copy:
            self.evaluate()
            return self.k_t, self.gamma, self.margin
        p = self.prob
        k_t, gamma, margin = self.fun(p.q.T, p.cut.T, p.feed, p.params)
        k_t = np.asarray(k_t).reshape(3, self.n, 3).transpose(1, 2, 0)
        return k_t, np.asarray(gamma).reshape(-1), np.asarray(margin).reshape(-1)


def best_worst(fn: Callable[[], object], repeats: int = REPEATS):
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), max(times), out


@dataclass
class Row:
    variant: str
    poses: int
    best_s: float
    worst_s: float
    rate: float = 0.0            # poses/s (best)
    us_per_pose: float = 0.0
    ratio: float = 0.0           # rate / baseline rate
    hours_1e8: float = 0.0
    meets_rate: bool = False
    meets_ratio: bool = False
    agreement: str = ""
    note: str = ""

    def finish(self, baseline_rate: float) -> Row:
        self.rate = self.poses / self.best_s
        self.us_per_pose = 1e6 * self.best_s / self.poses
        self.ratio = self.rate / baseline_rate
        self.hours_1e8 = THESIS_POSES / self.rate / 3600.0
        self.meets_rate = self.rate >= TARGET_RATE
        self.meets_ratio = self.ratio >= TARGET_RATIO
        return self


# ----------------------------------------------------------------------------- code generation
@dataclass
class Compiled:
    flags: str
    kernel: ca.Function | None
    build_s: float
    reason: str = ""


def compile_kernel(f: ca.Function, name: str, extra: tuple[str, ...]) -> Compiled:
    """Generate C for ``f`` (with CSE), compile with gcc, load with ``ca.external``."""
    gcc = shutil.which("gcc")
    flags = " ".join((*GCC_FLAGS, *extra))
    if gcc is None:
        return Compiled(flags, None, 0.0, "gcc not found on PATH")
    BUILD_DIR.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    kernel = ca.Function(name, f.sx_in(), f.call(f.sx_in()), f.name_in(), f.name_out(),
                         {"cse": True})
    gen = ca.CodeGenerator(f"{name}.c", {"with_header": False})
    gen.add(kernel)
    gen.generate(str(BUILD_DIR) + os.sep)
    lib = BUILD_DIR / f"{name}.so"
    cmd = [gcc, *GCC_FLAGS, *extra, "-shared", "-fPIC", str(BUILD_DIR / f"{name}.c"), "-o",
           str(lib), "-lm"]
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if done.returncode != 0 and "-march=native" in cmd:  # an old gcc or an odd CPU
        cmd.remove("-march=native")
        flags = flags.replace("-march=native", "").replace("  ", " ").strip()
        done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        return Compiled(flags, None, time.perf_counter() - t0,
                        f"gcc failed: {done.stderr.strip()[:200]}")
    ext = ca.external(name, str(lib))
    return Compiled(flags, ext, time.perf_counter() - t0)


# --------------------------------------------------------------------------------------- main
def machine() -> dict:
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    gcc = shutil.which("gcc")
    gcc_version = (subprocess.run([gcc, "-dumpfullversion"], capture_output=True, text=True)
                   .stdout.strip() if gcc else "not found")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return {"nproc": len(os.sched_getaffinity(0)), "cpu": cpu, "load_1min": load,
            "python": platform.python_version(),
            "casadi": ca.__version__, "pinocchio": pin.__version__, "numpy": np.__version__,
            "gcc": gcc_version}


@dataclass
class Report:
    machine: dict
    repeats: int
    n: int
    baseline_n: int
    drawn: int
    sigma_lin_min: float
    kernel_instructions: int
    kernel_instructions_cse: int
    baseline_agreement: str
    rows: list[Row] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    best: str = ""
    targets_met: bool = False
    wall_s: float = 0.0


def run(n: int = 100_000, baseline_n: int = 2_000, log: Callable[[str], None] | None = None,
        repeats: int = REPEATS) -> Report:
    """Run every variant and return the report (raises RuntimeError if the baseline disagrees)."""
    say = log or (lambda s: None)
    t_start = time.perf_counter()
    host = machine()  # before any work, so the load average is the others'
    if n % 2:
        n += 1
        say(f"n rounded up to {n} (even) so that both threads get equal halves")
    baseline_n = min(baseline_n, n)
    robot = load_robot()
    f = point_function(robot, "thesis", "isotropic", outputs=OUTPUTS)
    f_cse = ca.Function("cse", f.sx_in(), f.call(f.sx_in()), {"cse": True})
    say(f"sampling {n} reachable poses ...")
    prob = make_problem(robot, n)

    # (b) the reference: serial VM map through the zero-copy buffer (checked against the
    # ordinary call below, which is the same code path inside CasADi).
    vm_serial = Runner(f, prob, 1, zero_copy=True)
    say("casadi VM serial (buffer) ...")
    b_best, b_worst, ref = best_worst(vm_serial, repeats)
    ref = tuple(np.array(a, copy=True) for a in ref)

    # (a) the per-pose baseline on a subset, checked against the kernel.
    say(f"per-pose numpy/pinocchio baseline on {baseline_n} poses ...")
    base = Baseline(robot, np.zeros(3))
    base.run(prob, min(50, baseline_n))  # warm-up
    a_best, a_worst, base_out = best_worst(lambda: base.run(prob, baseline_n), repeats)
    agreement = compare(base_out, tuple(a[:baseline_n] for a in ref))
    if not agreement.ok:
        raise RuntimeError("the per-pose baseline disagrees with the CasADi kernel: "
                           + agreement.text())
    rows = [Row("numpy/pinocchio per pose (baseline)", baseline_n, a_best, a_worst,
                agreement="vs kernel: " + agreement.text(),
                note=f"subset of {baseline_n} poses")]
    baseline_rate = baseline_n / a_best

    def add(variant: str, runner: Runner, note: str = "") -> None:
        say(variant + " ...")
        best, worst, out = best_worst(runner, repeats)
        agr = compare(out, ref)
        if not agr.ok:
            report.skipped.append(f"{variant}: disagrees with the serial VM map: {agr.text()}")
            return
        rows.append(Row(variant, n, best, worst, agreement="vs VM serial: " + agr.text(),
                        note=note))

    report = Report(machine=host, repeats=repeats, n=n, baseline_n=baseline_n, drawn=prob.drawn,
                    sigma_lin_min=prob.sigma_lin_min, kernel_instructions=f.n_instructions(),
                    kernel_instructions_cse=f_cse.n_instructions(),
                    baseline_agreement=agreement.text(), rows=rows)
    add("casadi VM  f.map(n), python call", Runner(f, prob, 1, zero_copy=False))
    add("casadi VM  f.map(n,'thread',2), python call", Runner(f, prob, 2, zero_copy=False))
    rows.append(Row("casadi VM  serial map, zero-copy buffer", n, b_best, b_worst,
                    agreement="reference"))
    add("casadi VM  thread map x2, zero-copy buffer", Runner(f, prob, 2, zero_copy=True))

    for tag, extra in (("", ()), (" fast-math", (GCC_FAST_MATH,))):
        name = "cctmill_kernel" + ("_fastmath" if extra else "")
        say(f"generating and compiling {name} ...")
        comp = compile_kernel(f, name, extra)
        if comp.kernel is None:
            report.skipped.append(f"compiled C{tag}: {comp.reason}")
            continue
        note = f"gcc {comp.flags}; CSE; build {comp.build_s:.1f} s"
        add(f"compiled C{tag}  serial map, python call", Runner(comp.kernel, prob, 1, False), note)
        add(f"compiled C{tag}  thread map x2, python call", Runner(comp.kernel, prob, 2, False),
            note)
        add(f"compiled C{tag}  serial map, zero-copy buffer", Runner(comp.kernel, prob, 1, True),
            note)
        add(f"compiled C{tag}  thread map x2, zero-copy buffer",
            Runner(comp.kernel, prob, 2, True), note)

    for row in rows:
        row.finish(baseline_rate)
    fastest = max(rows[1:], key=lambda r: r.rate)
    report.best = fastest.variant
    report.targets_met = fastest.meets_rate and fastest.meets_ratio
    report.wall_s = time.perf_counter() - t_start
    return report


def _hms(hours: float) -> str:
    seconds = int(round(hours * 3600))
    h, rest = divmod(seconds, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}"


def format_table(report: Report) -> str:
    m = report.machine
    lines = [
        f"- machine: {m['nproc']} cores, {m['cpu']}; python {m['python']}, casadi {m['casadi']}, "
        f"pinocchio {m['pinocchio']}, numpy {m['numpy']}, gcc {m['gcc']}; load average at the "
        f"start {m['load_1min']:.2f} (timings on a shared 2-core VM vary by ±20 % run to run)",
        f"- kernel: point_function(robot, 'thesis', 'isotropic', outputs={OUTPUTS}), "
        f"{report.kernel_instructions} SX instructions ({report.kernel_instructions_cse} with CSE)",
        f"- poses: {report.n} random reachable (drew {report.drawn}; "
        f"smallest kept σ_min(J_v) {report.sigma_lin_min * 1e3:.1f} mm/rad), Case 1 cut with "
        f"Y_o along each pose's tool axis, feed 1 mm/s",
        f"- baseline check on {report.baseline_n} poses: {report.baseline_agreement}",
        f"- targets: >= {TARGET_RATE:,.0f} poses/s and >= {TARGET_RATIO:.0f}x the per-pose baseline;"
        f" best of {report.repeats} repeats (worst in brackets)",
        "- python call = the ordinary `fm(q, cut, feed, params)` (numpy converted to DM and the "
        "DM results back to numpy, inside the timing); zero-copy buffer = `Function.buffer()` "
        "evaluating straight on numpy memory (q and cut mapped, feed and params shared); "
        "thread map x2 = two std::threads, each a serial map over half the poses",
        "- every variant's K_t, γ and margin agree with the serial VM map to the tolerances of "
        "the baseline check; rates are reported only after that check",
        "",
        "| variant | poses | poses/s | µs/pose (worst) | × baseline | 1e8 poses (h:mm:ss) "
        "| ≥500k/s | ≥50× |",
        "|---|---:|---:|---:|---:|---:|:---:|:---:|",
    ]
    for r in report.rows:
        worst_us = 1e6 * r.worst_s / r.poses
        lines.append(
            f"| {r.variant} | {r.poses:,} | {r.rate:,.0f} | {r.us_per_pose:.2f} ({worst_us:.2f}) "
            f"| {r.ratio:,.1f} | {_hms(r.hours_1e8)} | {'yes' if r.meets_rate else 'no'} "
            f"| {'yes' if r.meets_ratio else 'no'} |")
    lines.append("")
    seen = set()
    for r in report.rows:
        group = r.variant.split("  ")[0]
        if r.note and (group, r.note) not in seen:
            seen.add((group, r.note))
            lines.append(f"- {group}: {r.note}")
    for s in report.skipped:
        lines.append(f"- skipped {s}")
    lines.append("")
    lines.append(f"best: {report.best} — targets "
                 f"{'MET' if report.targets_met else 'NOT met'}; wall time {report.wall_s:.0f} s")
    return "\n".join(lines)


def to_json(report: Report) -> dict:
    d = asdict(report)
    d["targets"] = {"rate_poses_per_s": TARGET_RATE, "ratio_vs_baseline": TARGET_RATIO,
                    "thesis_poses": THESIS_POSES}
    d["tolerances"] = {"kt_rel": KT_REL_TOL, "gamma_abs_rad": GAMMA_ABS_TOL,
                       "margin_rel": MARGIN_REL_TOL}
    return d


def main(argv: list[str] | None = None) -> Report:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=100_000, help="number of poses (default 100000)")
    ap.add_argument("--baseline-n", type=int, default=2_000,
                    help="poses for the per-pose baseline (default 2000)")
    ap.add_argument("--repeats", type=int, default=REPEATS,
                    help=f"timing repeats per variant, best and worst reported (default {REPEATS})")
    ap.add_argument("--json", action="store_true", help="print the report as JSON")
    args = ap.parse_args(argv)
    if args.n < 2 or args.baseline_n < 1 or args.repeats < 1:
        ap.error("--n must be >= 2, --baseline-n and --repeats >= 1")
    log = None if args.json else (lambda s: print(s, file=sys.stderr, flush=True))
    report = run(args.n, args.baseline_n, log, args.repeats)
    print(json.dumps(to_json(report), indent=2) if args.json else format_table(report))
    return report


if __name__ == "__main__":
    main()
