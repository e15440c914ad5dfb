"""Homing, machine coordinates and canned cycles of the G-code interpreter (private): G28/G30,
G53, G81/G82 expanded into moves and the other cycles tracked; conventions in
:mod:`robot_io.gcode`."""

from __future__ import annotations

from typing import TYPE_CHECKING

from robot_io.gcode import _words as W

if TYPE_CHECKING:
    from robot_io.gcode._interp import _Run

__all__ = ["canned_cycle", "group0_move"]


def group0_move(run: _Run, key: int, col: int, words: dict) -> None:
    st = run.st
    named = [i for i, k in enumerate("XYZ") if k in words]
    named_rot = [k for k in "ABC" if k in words]
    if key == 530:
        if st.motion not in (0, 10):
            run.problem(col, "machine_coordinates", "G53 needs G0 or G1 in force; add G0",
                        skip="machine_coordinates")
        pos, rot = list(st.pos), dict(st.rot)
        for i in named:
            pos[i] = None
        for k in named_rot:
            rot[k] = None
        st.pos, st.rot, run.last_tip = pos, rot, None
        run.skipped["machine_coordinates"] += 1
        run.warn(col, "machine_coordinates", "G53 move in machine coordinates skipped: its "
                 "end is unknown in the workpiece frame until the axes are programmed again")
        return
    run.meta["homing_blocks"] += 1
    pos, rot = run.target(words)
    if pos != st.pos or rot != st.rot:   # the intermediate point
        run.emit(0, col, pos, rot, None)
    home = run.opts.home_position
    if not named and not named_rot:
        named, named_rot = [0, 1, 2], ["A", "B", "C"]
    pos, rot = list(st.pos), dict(st.rot)
    for i in named:
        pos[i] = None if home is None else home[i]
    for k in named_rot:
        rot[k] = None if home is None else 0.0
    if home is not None:
        run.emit(0, col, pos, rot, None)
    else:
        st.pos, st.rot, run.last_tip = pos, rot, None


def canned_cycle(run: _Run, code: int, col: int, words: dict) -> None:
    st = run.st
    name = W.code_name("G", code)
    z0 = st.pos[2]
    reason = None
    if st.plane != 170:
        reason = f"{name} outside G17 is not supported; program the moves"
    elif st.inverse_time:
        reason = f"{name} in G93 inverse time: give the cycle a G94 feed"
    elif z0 is None:
        reason = f"{name} from an unknown Z: move Z absolutely before the cycle"
    if reason is not None:
        run.problem(col, "canned_cycle", f"{reason}, or {W.fix_hint()}", skip="canned_cycle")
        return
    scale = st.scale
    r_abs, z_abs = st.cycle_r, st.cycle_z
    if "R" in words:
        r_abs = words["R"][0] * scale + (0.0 if st.absolute else z0)
    if "Z" in words and r_abs is not None:
        z_abs = words["Z"][0] * scale + (0.0 if st.absolute else r_abs)
    reps = 1
    if "L" in words:
        lv = words["L"][0]
        reps = int(lv) if lv == int(lv) and 1 <= lv <= W.MAX_CYCLE_REPEAT else 0
    if r_abs is None or z_abs is None or reps == 0:
        run.problem(col, "canned_cycle", f"{name} needs R (retract plane), Z (bottom) and "
                    f"an integer L in 1…{W.MAX_CYCLE_REPEAT} if any; add them, or "
                    f"{W.fix_hint()}", skip="canned_cycle")
        return
    if run.cycle_repeats + reps - 1 > W.MAX_CYCLE_REPEATS:
        run.problem(col, "canned_cycle", f"{name} L{reps} makes the L repeats of the program "
                    f"more than {W.MAX_CYCLE_REPEATS:,} (MAX_CYCLE_REPEATS) in all; program the "
                    f"holes as moves or split the program, or {W.fix_hint()}",
                    skip="canned_cycle")
        return
    run.cycle_repeats += reps - 1
    st.cycle_r, st.cycle_z = r_abs, z_abs
    clear = r_abs if st.retract_r_plane else max(z0, r_abs)
    expand = code in W.EXPANDED_CYCLES
    if not expand:
        run.skipped["canned_cycle_not_expanded"] += 1
        run.warn(col, "canned_cycle_not_expanded", f"canned cycle {name} not expanded: its "
                 "moves are missing from the toolpath (the position after it is kept)")
    elif st.feed_raw is None:
        run.problem(col, "missing_feed", f"{name} without a feed rate; add an F word",
                    skip="missing_feed")
    rot = st.rot
    x, y = st.pos[0], st.pos[1]
    for rep in range(reps):
        if "X" in words:
            v = words["X"][0] * scale
            x = v if st.absolute else (None if x is None else x + v)
        if "Y" in words:
            v = words["Y"][0] * scale
            y = v if st.absolute else (None if y is None else y + v)
        # (kind, x, y, z); z None = stay at the current height
        steps = [(0, x, y, None), (0, x, y, r_abs), (10, x, y, z_abs), (0, x, y, clear)]
        if rep == 0 and z0 < r_abs:
            steps.insert(0, (0, st.pos[0], st.pos[1], r_abs))
        for kind, sx, sy, sz in steps:
            target = [sx, sy, st.pos[2] if sz is None else sz]
            if target == st.pos:
                continue
            if expand:
                run.emit(kind, col, target, rot, None)
            else:
                st.pos = target
                run.last_tip = None
        if expand and code == 820 and "P" in words:
            run.meta["dwell_s"] += max(words["P"][0], 0.0)
