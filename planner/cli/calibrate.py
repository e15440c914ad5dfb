"""``cctmill calibrate``: fit the model to a cell's cut records, write an overlay (docs/calibration.md).

Thin shell over :func:`planner.calibrate.run.calibrate` and
:func:`planner.calibrate.run.write_calibration`.
"""

from __future__ import annotations

import argparse
import json

__all__ = ["register"]


def register(sub) -> None:
    """Add the ``calibrate`` subcommand to ``sub`` (argparse sub-parsers)."""
    from planner.calibrate.run import FITS
    from planner.cli._common import add_output

    p = sub.add_parser(
        "calibrate", help="fit the model to a cell's cut records; write an overlay for the job",
        description="Read cut records (JSON Lines, docs/calibration.md) and a job; fit the "
                    "cutting coefficients (least squares of the mean forces, with 95 % "
                    "confidence intervals), the joint stiffness scale (measured deflections, "
                    "else chatter frequencies), with --fit process the gain on K_p that makes "
                    "the eigen criterion agree with the verdicts, and with --fit boundary "
                    "P(chatter) over the criterion's margin, a_p and rpm (logistic "
                    "regression); write the fitted "
                    "values as an overlay the job reads with [calibration] overlay = \"FILE\", "
                    "and a fit-quality report FILE.report.json beside it. A fit the records "
                    "cannot support is refused with the reason.")
    p.add_argument("records", nargs="+", metavar="RECORDS", help="cut record files (.jsonl)")
    p.add_argument("--job", required=True, metavar="JOB.toml", help="the job (cell, tool, "
                   "nominal model)")
    add_output(p, "-o", "--output", kind="file", required=True, metavar="OVERLAY.toml",
               help="the overlay to write")
    p.add_argument("--fit", default="coefficients,stiffness",
                   help=f"comma-separated fits: {', '.join(FITS)} (default "
                        "coefficients,stiffness)")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from planner.calibrate.run import calibrate, write_calibration

    fits = [f.strip() for f in args.fit.split(",") if f.strip()]
    # progress bars on stderr, on a terminal only (planner/_progress.py): silent in scripts
    result = calibrate(args.records, args.job, fits, progress=not args.json)
    overlay, report = write_calibration(result, args.output)
    if args.json:
        print(json.dumps(result.report(), indent=2))
    else:
        print(result.summary())
        print(f"wrote {overlay} and {report}")
    return 0
