"""How a point analysis is shown: JSON for scripts (SI, angles in degrees), a table for people;
and what the report's section table adds to plan.json (a_e/a_p, the joint a robot-bound section
waits for)."""

from __future__ import annotations

from typing import Any

import numpy as np

from models.point import PointAnalysis, StabilityCharacteristic

__all__ = ["analysis_json", "analysis_table", "characteristic_table", "limiting_joints",
           "section_engagement"]


def _list(a: np.ndarray) -> list:
    return np.asarray(a, float).round(12).tolist()


def analysis_json(a: PointAnalysis, cct: bool) -> dict[str, Any]:
    """The ``cctmill analyze --json`` object. Lengths/forces/stiffnesses SI; angles in degrees."""
    out: dict[str, Any] = {
        "process_model": a.process_model,
        "mass_model": a.mass_model,
        "criterion": a.criterion,
        "cct": cct,
        "feed_m_s": a.feed,
        "feed_per_tooth_m": a.feed_per_tooth,
        "force_N": _list(a.force_o),
        "force_base_N": _list(a.force_base),
        "force_resultant_N": a.force,
        "alpha_deg": float(np.degrees(a.alpha)),
        "beta_deg": float(np.degrees(a.beta)),
        "gamma_deg": float(np.degrees(a.gamma)),
        "k_pxo_N_per_m": a.k_pxo,
        "k_px_N_per_m": a.k_px,
        "k_py_N_per_m": a.k_py,
        "k_max_N_per_m": a.k_max,
        "k_min_N_per_m": a.k_min,
        "k_p_N_per_m": _list(a.k_p),
        "plane_axes_base": _list(a.plane.T),
        "A_N_per_m": _list(a.a),
        "eig_A": _list(a.eig),
        "stable": bool(a.stable),
        "stable_eigen": bool(a.stable_eigen),
        "margin_N_per_m": a.margin,
        "gamma_window_margin_deg": float(np.degrees(a.gamma_margin)),
        "floquet_spectral_radius": a.floquet_radius,
        "stiffness_N_per_m": _list(a.stiffness),
        "compliance_m_per_N": _list(a.compliance),
        "principal_stiffness_N_per_m": _list(a.principal_values),
        "principal_directions_base": _list(a.principal_directions.T),
        "deflection_m": _list(a.deflection),
        "tcp_position_m": _list(a.tcp_position),
        "tool_axis_base": _list(a.tool_axis),
        "tool_axis_angle_deg": float(np.degrees(a.tool_axis_angle)),
        "jacobian_sigma_min_m": a.jacobian_sigma_min,
        "warnings": list(a.warnings),
    }
    if a.natural_frequencies is not None:
        out["natural_frequencies_hz"] = _list(a.natural_frequencies)
    return out


def analysis_table(a: PointAnalysis, cct: bool) -> str:
    """A readable table of one analysis (engineering units)."""
    f = a.force_o
    lines = [
        f"model            process {a.process_model}, mass {a.mass_model}, criterion "
        f"{a.criterion}, stiffness {'CCT' if cct else 'conventional'}",
        f"feed             {a.feed * 1e3:.3f} mm/s  ({a.feed_per_tooth * 1e6:.2f} um/tooth)",
        f"force (Xo,Yo,Zo) {f[0]:8.2f} {f[1]:8.2f} {f[2]:8.2f} N   |F| = {a.force:.2f} N",
        f"force (base)     {a.force_base[0]:8.2f} {a.force_base[1]:8.2f} {a.force_base[2]:8.2f} N",
        f"alpha, beta      {np.degrees(a.alpha):8.2f} {np.degrees(a.beta):8.2f} deg",
        f"gamma            {np.degrees(a.gamma):8.2f} deg   (force to K_max direction)",
        f"K_px, K_py       {a.k_px:10.4g} {a.k_py:10.4g} N/m",
        f"K_max, K_min     {a.k_max:10.4g} {a.k_min:10.4g} N/m",
        f"K_p              [[{a.k_p[0, 0]:.4g}, {a.k_p[0, 1]:.4g}], "
        f"[{a.k_p[1, 0]:.4g}, {a.k_p[1, 1]:.4g}]] N/m",
        "eig(A)           " + ", ".join(
            f"{re:.4g}{im:+.4g}i" if im else f"{re:.4g}" for re, im in a.eig) + " N/m",
        f"margin           {a.margin:10.4g} N/m  -> {'STABLE' if a.stable else 'UNSTABLE'}"
        + (f" (floquet: rho {a.floquet_radius:.4f}; eigen "
           f"{'stable' if a.stable_eigen else 'unstable'})" if a.floquet_radius is not None else ""),
        f"deflection       {a.deflection[0] * 1e3:8.4f} {a.deflection[1] * 1e3:8.4f} "
        f"{a.deflection[2] * 1e3:8.4f} mm  (|d| = {np.linalg.norm(a.deflection) * 1e3:.4f} mm)",
        f"TCP (base)       {a.tcp_position[0] * 1e3:9.2f} {a.tcp_position[1] * 1e3:9.2f} "
        f"{a.tcp_position[2] * 1e3:9.2f} mm",
    ]
    if a.natural_frequencies is not None:
        nf = a.natural_frequencies
        lines.append(f"2-DOF modes      {nf[0]:.2f} Hz (K_max), {nf[1]:.2f} Hz (K_min)")
    pv, pd = a.principal_values, a.principal_directions
    lines.append("principal K_t        " + "   ".join(
        f"{pv[i]:.4g} N/m along ({pd[0, i]:+.3f},{pd[1, i]:+.3f},{pd[2, i]:+.3f})"
        for i in range(3)))
    k = a.stiffness
    lines.append("K_t (base, N/m)  " + "\n                 ".join(
        " ".join(f"{v:11.4g}" for v in row) for row in k))
    lines += [f"warning: {w}" for w in a.warnings]
    return "\n".join(lines)


def characteristic_table(ch: StabilityCharacteristic) -> str:
    """One row per feed: feed, |F|, γ, margin, verdict; then the point's feed limit."""
    criterion = ch.points[0].criterion if ch.points else "eigen"
    unit = {"gamma_window": "deg", "floquet": "1-rho"}.get(criterion, "N/m")
    rows = [f"{'feed mm/s':>10} {'|F| N':>8} {'gamma deg':>10} {'margin ' + unit:>14}  verdict"]
    for p, m in zip(ch.points, ch.margin, strict=True):
        mm = np.degrees(m) if unit == "deg" else m
        verdict = "stable" if p.stable else "UNSTABLE"
        if p.force > ch.force_limit:
            verdict += ", over force limit"
        rows.append(f"{p.feed * 1e3:10.3f} {p.force:8.2f} {np.degrees(p.gamma):10.3f} "
                    f"{mm:14.5g}  {verdict}")
    rows.append(f"feed limit {ch.feed_limit * 1e3:.3f} mm/s, bound by {ch.binding} "
                f"(force limit {ch.force_limit:.0f} N)")
    return "\n".join(rows)


#: Shortest step along the path a derivative is taken over [m] (a repeated sample is skipped
#: rather than divided by).
_DS_MIN = 1e-9
#: A limit is "reached" from this share of it on (the estimates are a few per cent off).
_NEAR_LIMIT = 0.8


def limiting_joints(res) -> dict[int, str]:
    """For each robot-bound section (its plan.json ``index``), what holds it back, nearest its
    limit over the section: a joint's speed |q̇| / q̇_max (``"A3 speed 99 %"``), a joint's
    acceleration |q̈| / q̈_max (``"A1 accel. 97 %"``), or, when no joint comes as near, the path
    acceleration limit toppra also holds (``"path accel. 100 % (A2 accel. 68 %)"``, the nearest
    joint in brackets). Where none comes within :data:`_NEAR_LIMIT` of its limit in the samples
    (a short section between them, toppra's own grid), it says so and names the nearest.

    Estimated from the timed samples, so a few per cent either way: q̇ = q' ṡ and
    q̈ = q'' ṡ² + q' s̈ with q', q'' the derivatives of the joint path along s and
    s̈ = ½ d(ṡ²)/ds (``res.timing.speed``).
    """
    prep, timing = res.prep, res.timing
    data, names = prep.robot.data, prep.kinematics.joint_names
    s = np.asarray(prep.path.s, float)
    q = np.asarray(prep.kinematics.q, float)
    sd = np.asarray(timing.speed, float)
    if s.size < 3:
        return {}
    keep = np.concatenate([[True], np.diff(s) > _DS_MIN])     # repeated samples: no derivative
    at = np.cumsum(keep) - 1
    sk, qk, vk = s[keep], q[keep], sd[keep]
    if sk.size < 3:
        return {}
    dq = np.gradient(qk, sk, axis=0)
    ddq = np.gradient(dq, sk, axis=0)
    sdd = 0.5 * np.gradient(vk ** 2, sk)
    speed = (np.abs(dq * vk[:, None]) / np.asarray(data.velocity, float))[at]
    acc = (np.abs(ddq * vk[:, None] ** 2 + dq * sdd[:, None])
           / np.asarray(data.acceleration, float))[at]
    path_acc = (np.abs(sdd) / float(res.limits.path_acc_max))[at]
    out: dict[int, str] = {}
    for r in res.section_rows:
        if not r.get("robot_limited"):
            continue
        a, b = int(r["sample_start"]), int(r["sample_stop"])
        if b <= a:
            continue
        v = speed[a:b].max(axis=0)
        w = acc[a:b].max(axis=0)
        j_v, j_a = int(np.argmax(v)), int(np.argmax(w))
        joint = (f"{names[j_v]} speed {100 * v[j_v]:.0f} %" if v[j_v] >= w[j_a]
                 else f"{names[j_a]} accel. {100 * w[j_a]:.0f} %")
        p = float(path_acc[a:b].max())
        nearest = (joint if max(v[j_v], w[j_a]) >= p else f"path accel. {100 * p:.0f} % ({joint})")
        if max(v[j_v], w[j_a], p) < _NEAR_LIMIT:
            nearest = f"none reached in the samples; nearest {nearest}"
        out[int(r["index"])] = nearest
    return out


def section_engagement(res) -> dict[int, tuple[float, float]]:
    """Largest a_e and a_p over each cut section [m], by its plan.json ``index``."""
    e = res.prep.engagement
    out: dict[int, tuple[float, float]] = {}
    for r in res.section_rows:
        a, b = int(r["sample_start"]), int(r["sample_stop"])
        if r["kind"] != "cut" or b <= a:
            continue
        out[int(r["index"])] = (float(np.max(e.a_e[a:b])), float(np.max(e.a_p[a:b])))
    return out
