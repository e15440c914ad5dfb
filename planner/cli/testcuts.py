"""``cctmill testcuts``: propose the next test passes in a job's cell; KRL + planned records
(docs/calibration.md). Thin shell over :func:`planner.calibrate.run.testcuts`."""

from __future__ import annotations

import argparse

from models.errors import InputError

__all__ = ["register"]


def _range(text: str | None, flag: str) -> tuple[float, float] | None:
    if text is None:
        return None
    try:
        lo, hi = (float(v) for v in text.split(":"))
    except ValueError:
        raise InputError(flag, f"need LO:HI, got {text!r}") from None
    if not 0 < lo < hi:
        raise InputError(flag, f"need 0 < LO < HI, got {text!r}")
    return lo, hi


def register(sub) -> None:
    """Add the ``testcuts`` subcommand to ``sub`` (argparse sub-parsers)."""
    from planner.cli._common import add_output

    p = sub.add_parser(
        "testcuts", help="propose the next test passes in the job's cell (KRL + planned records)",
        description="Propose N short test passes over the job's stock, where the current "
                    "stability boundary (fitted from --records) is most uncertain (value of "
                    "information), or space-filling without records, or identification slots "
                    "for the coefficients and stiffness (--design identification). Writes "
                    "DIR/TESTCUTS.src/.dat and DIR/planned.jsonl; with --simulate TRUTH.toml "
                    "runs them in a simulated true cell (time-domain model, regeneration, force "
                    "noise) and writes DIR/records.jsonl.")
    p.add_argument("job", metavar="JOB.toml", help="the job (cell, tool, stock)")
    p.add_argument("-n", type=int, default=8, help="number of passes (default 8)")
    add_output(p, "-o", "--output", kind="folder", required=True, metavar="DIR",
               help="folder for the KRL program and the records")
    p.add_argument("--records", nargs="*", default=(), metavar="RECORDS",
                   help="cut records so far (their verdicts give the current boundary)")
    p.add_argument("--design", choices=("boundary", "identification", "along-job"),
                   default="boundary",
                   help="boundary (default: over the stock top), identification (slots over the "
                        "chip-load range) or along-job (passes imitating the job's own planned "
                        "sections: pose, feed direction, a_e; a_p varied)")
    p.add_argument("--rpm-range", default=None, metavar="LO:HI",
                   help="spindle speeds to try [rpm] (default 0.5..1.5 x the job's)")
    p.add_argument("--ap-range-mm", default=None, metavar="LO:HI",
                   help="axial depths to try [mm] (default 0.5 .. the job's)")
    p.add_argument("--ae-mm", type=float, default=None, help="radial depth [mm] (default the job's)")
    p.add_argument("--simulate", default=None, metavar="TRUTH.toml",
                   help="run the passes in a simulated true cell ([truth] joint_scale, "
                        "coefficient_factor, ...; docs/calibration.md)")
    p.add_argument("--seed", type=int, default=0, help="seed of the design and the noise")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from planner.calibrate.run import testcuts

    result = testcuts(args.job, args.n, args.output, records=args.records,
                      truth_file=args.simulate, design=args.design,
                      rpm=_range(args.rpm_range, "--rpm-range"),
                      ap_mm=_range(args.ap_range_mm, "--ap-range-mm"), ae_mm=args.ae_mm,
                      seed=args.seed, progress=True)
    print(result.summary())
    return 0
